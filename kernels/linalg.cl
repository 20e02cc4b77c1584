// linalg.cl — the vector operations of the tomography solvers (lib/tomo/tomo.cpp) on the device:
// axpy-type updates, element-wise products, non-negativity, partial dot products, and the
// weighted forward-difference operator of the TV regulariser with its exact transpose.
#include "config.cl"

// y += a·x
__kernel void axpy(const int n, const real a, __global const real* restrict x,
                   __global real* restrict y) {
  const int i = get_global_id(0);
  if (i < n) y[i] += a * x[i];
}

// y = x + b·y
__kernel void xpby(const int n, __global const real* restrict x, const real b,
                   __global real* restrict y) {
  const int i = get_global_id(0);
  if (i < n) y[i] = x[i] + b * y[i];
}

// y = a·x
__kernel void scale_copy(const int n, const real a, __global const real* restrict x,
                         __global real* restrict y) {
  const int i = get_global_id(0);
  if (i < n) y[i] = a * x[i];
}

// y = x ⊙ y
__kernel void multiply(const int n, __global const real* restrict x, __global real* restrict y) {
  const int i = get_global_id(0);
  if (i < n) y[i] *= x[i];
}

// x = 1 / x where x > 0, else 0 (SIRT's row and column normalisations: a ray that misses the box
// or a voxel no ray meets gets weight 0, never Inf).
__kernel void safe_reciprocal(const int n, __global real* restrict x) {
  const int i = get_global_id(0);
  if (i < n) x[i] = x[i] > (real)0 ? (real)1 / x[i] : (real)0;
}

// x = max(x, 0); partial[g] gets the sum of what was removed by work-item g (0: nothing moved).
__kernel void clamp_nonneg(const int n, __global real* restrict x,
                           __global real* restrict partial) {
  const int g = get_global_id(0), stride = get_global_size(0);
  real removed = (real)0;
  for (int i = g; i < n; i += stride)
    if (x[i] < (real)0) {
      removed -= x[i];
      x[i] = (real)0;
    }
  partial[g] = removed;
}

// partial[g] = Σ x[i]·y[i] over i ≡ g (mod the global size), compensated (Kahan–Babuška) so that
// float32 keeps its precision over long vectors; the host adds the partials in double.
__kernel void dot_partial(const int n, __global const real* restrict x,
                          __global const real* restrict y, __global real* restrict partial) {
  const int g = get_global_id(0), stride = get_global_size(0);
  real sum = (real)0, comp = (real)0;
  for (int i = g; i < n; i += stride) {
    const real term = x[i] * y[i], t = sum + term;
    comp += fabs(sum) >= fabs(term) ? (sum - t) + term : (term - t) + sum;
    sum = t;
  }
  partial[g] = sum + comp;
}

// --- Total variation: forward differences (D x)_{i,a} = x_{i+e_a} − x_i (0 on the upper face),
// weighted per voxel: out[3i+a] = sw[i]·(D x)_{i,a}. ----------------------------------------------

__kernel void tv_forward(const int4 dims, __global const real* restrict x,
                         __global const real* restrict sw, __global real* restrict out) {
  const int i = get_global_id(0), n = dims.x * dims.y * dims.z;
  if (i >= n) return;
  const int ix = i % dims.x, iy = (i / dims.x) % dims.y, iz = i / (dims.x * dims.y);
  const real xi = x[i], s = sw[i];
  out[3 * i + 0] = ix + 1 < dims.x ? s * (x[i + 1] - xi) : (real)0;
  out[3 * i + 1] = iy + 1 < dims.y ? s * (x[i + dims.x] - xi) : (real)0;
  out[3 * i + 2] = iz + 1 < dims.z ? s * (x[i + dims.x * dims.y] - xi) : (real)0;
}

// Voxel i's index steps along x, y, z and whether it has a next and a previous neighbour on each
// axis: the forward differences that touch it (tv_adjoint, tv_diagonal).
inline void tv_neighbours(int4 dims, int i, int* step, bool* has_next, bool* has_prev) {
  const int ix = i % dims.x, iy = (i / dims.x) % dims.y, iz = i / (dims.x * dims.y);
  step[0] = 1, step[1] = dims.x, step[2] = dims.x * dims.y;
  has_next[0] = ix + 1 < dims.x, has_next[1] = iy + 1 < dims.y, has_next[2] = iz + 1 < dims.z;
  has_prev[0] = ix > 0, has_prev[1] = iy > 0, has_prev[2] = iz > 0;
}

// out += a · Dᵀ(sw ⊙ g), the exact transpose of tv_forward (a gather: no atomics).
__kernel void tv_adjoint(const int4 dims, const real a, __global const real* restrict g,
                         __global const real* restrict sw, __global real* restrict out) {
  const int i = get_global_id(0), n = dims.x * dims.y * dims.z;
  if (i >= n) return;
  int step[3];
  bool has_next[3], has_prev[3];
  tv_neighbours(dims, i, step, has_next, has_prev);
  real sum = (real)0;
  for (int k = 0; k < 3; ++k) {
    if (has_next[k]) sum -= sw[i] * g[3 * i + k];
    if (has_prev[k]) sum += sw[i - step[k]] * g[3 * (i - step[k]) + k];
  }
  out[i] += a * sum;
}

// out[i] = base[i] + 2·(LᵀL)_ii of the TV rows L = S·D (S = diag(sw)): twice the diagonal of the
// regulariser's Hessian, which bounds its Gershgorin row sums — SIRT's column weights with a
// regulariser (lib/tomo/tomo.cpp): a voxel barely touched by rays then takes a step the
// regulariser's curvature allows, not 1/(Nᵀ1) ≈ 1e12 times its gradient.
__kernel void tv_diagonal(const int4 dims, __global const real* restrict sw,
                          __global const real* restrict base, __global real* restrict out) {
  const int i = get_global_id(0), n = dims.x * dims.y * dims.z;
  if (i >= n) return;
  int step[3];
  bool has_next[3], has_prev[3];
  tv_neighbours(dims, i, step, has_next, has_prev);
  real d = (real)0;
  for (int k = 0; k < 3; ++k) {
    if (has_next[k]) d += sw[i] * sw[i];
    if (has_prev[k]) d += sw[i - step[k]] * sw[i - step[k]];
  }
  out[i] = base[i] + (real)2 * d;
}

// The lagged-diffusivity weights of smoothed isotropic TV, λ Σ_i sqrt(|(D x)_i|² + ε²):
// sw[i] = sqrt(λ)·(|(D x)_i|² + ε²)^(−1/4), so that sw² is the weight of its quadratic majoriser.
__kernel void tv_weights(const int4 dims, const real epsilon, const real sqrt_lambda,
                         __global const real* restrict x, __global real* restrict sw) {
  const int i = get_global_id(0), n = dims.x * dims.y * dims.z;
  if (i >= n) return;
  const int ix = i % dims.x, iy = (i / dims.x) % dims.y, iz = i / (dims.x * dims.y);
  const real xi = x[i];
  const real dx = ix + 1 < dims.x ? x[i + 1] - xi : (real)0;
  const real dy = iy + 1 < dims.y ? x[i + dims.x] - xi : (real)0;
  const real dz = iz + 1 < dims.z ? x[i + dims.x * dims.y] - xi : (real)0;
  sw[i] = sqrt_lambda * rsqrt(sqrt(dx * dx + dy * dy + dz * dz + epsilon * epsilon));
}
