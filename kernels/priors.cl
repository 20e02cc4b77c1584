// priors.cl — smoothness priors on the density (lib/reconstruct/priors.cpp): smoothed isotropic total
// variation and L2 smoothness of the forward differences, their value and their gradient added to
// the loss gradient. Each voxel gathers from its neighbours: no atomics, a deterministic result.
#include "config.cl"

// Forward differences (D x)_a = x_{i+e_a} − x_i at voxel (ix, iy, iz), 0 across the upper faces.
inline real3 forward_differences(const int4 dims, __global const real* restrict x, const int ix,
                                 const int iy, const int iz) {
  const int i = (iz * dims.y + iy) * dims.x + ix;
  const real xi = x[i];
  return (real3)(ix + 1 < dims.x ? x[i + 1] - xi : (real)0,
                 iy + 1 < dims.y ? x[i + dims.x] - xi : (real)0,
                 iz + 1 < dims.z ? x[i + dims.x * dims.y] - xi : (real)0);
}

// With φ_i = sqrt(|(D x)_i|² + ε²), the prior is
//   R(x) = tv · mean_i (φ_i − ε) + smooth · mean_i |(D x)_i|²,
// and dR/dx_j = Σ_i w_i (D x)_i · d(D x)_i/dx_j with w_i = (tv/φ_i + 2·smooth) / V: voxel j is the
// lower end of its own differences and the upper end of its lower neighbours' ones. A grid-stride
// loop; partial[g] receives work-item g's share of R (summed on the host in a fixed order).
// inv_n = 1/V, V the whole volume's voxels (given by the host: no device division). Only the
// voxels of planes first <= iz < dims.w get their gradient, and only their own terms count in R:
// a slab of a volume split in z (lib/reconstruct/reconstruct_domain.cpp) holds the plane below
// it (first = 1: its lower neighbours' terms reach its first plane) and the plane it shares with
// the next slab (dims.w = dims.z − 1: that plane's terms and gradient are the next slab's), so each
// voxel's gradient is summed whole, in one process's order, by one worker.
__kernel void density_prior(const int4 dims, const int first, const real tv, const real smooth,
                            const real epsilon, const real inv_n, __global const real* restrict x,
                            __global real* restrict grad, __global real* restrict partial) {
  const int g = get_global_id(0), stride = get_global_size(0);
  const int n = dims.x * dims.y * dims.z;
  real sum = (real)0;
  for (int j = g; j < n; j += stride) {
    const int ix = j % dims.x, iy = (j / dims.x) % dims.y, iz = j / (dims.x * dims.y);
    if (iz < first || iz >= dims.w) continue;
    // The terms of this voxel: its own and its x, y and z neighbours'.
    const real3 d = forward_differences(dims, x, ix, iy, iz);
    const real d2 = dot(d, d), phi = sqrt(d2 + epsilon * epsilon);
    sum += tv * (phi - epsilon) + smooth * d2;
    real gj = -(tv / phi + (real)2 * smooth) * inv_n * (d.x + d.y + d.z);
    if (ix > 0) {
      const real3 e = forward_differences(dims, x, ix - 1, iy, iz);
      gj += (tv / sqrt(dot(e, e) + epsilon * epsilon) + (real)2 * smooth) * inv_n * e.x;
    }
    if (iy > 0) {
      const real3 e = forward_differences(dims, x, ix, iy - 1, iz);
      gj += (tv / sqrt(dot(e, e) + epsilon * epsilon) + (real)2 * smooth) * inv_n * e.y;
    }
    if (iz > 0) {
      const real3 e = forward_differences(dims, x, ix, iy, iz - 1);
      gj += (tv / sqrt(dot(e, e) + epsilon * epsilon) + (real)2 * smooth) * inv_n * e.z;
    }
    grad[j] += gj;
  }
  partial[g] = sum * inv_n;
}
