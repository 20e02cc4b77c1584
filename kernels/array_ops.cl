// array_ops.cl — the device arrays' own operations (lib/runtime/device_array.cpp, lib/session/session.cpp): the
// volume check run when a session's densities are set, reductions to the loss and the per-view
// sums, conversions between float32 and float64, and the gathers and column copies that leave
// a result's parts in arrays of their own — so that nothing has to come back to the host.
#include "config.cl"

// IVR_ACC_F64: sums accumulate in double (devices with cl_khr_fp64), else in float — over a
// tree of fixed shape either way, so the same inputs give the same bits on every run.
#ifndef IVR_ACC_F64
#define IVR_ACC_F64 IVR_F64
#endif
#if IVR_ACC_F64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double acc;
#else
typedef float acc;
#endif

// Work-group size of the reductions below (the host launches exactly this many items a group).
#ifndef IVR_REDUCE_SIZE
#define IVR_REDUCE_SIZE 256
#endif

// Tree sum of scratch[0 .. IVR_REDUCE_SIZE) into scratch[0]; every item of the group calls it.
inline void group_sum(__local acc* scratch, const int lid) {
  for (int span = IVR_REDUCE_SIZE / 2; span > 0; span /= 2) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < span) scratch[lid] += scratch[lid + span];
  }
  barrier(CLK_LOCAL_MEM_FENCE);
}

// Whether a value is refused: not finite, or negative unless allowed.
inline bool refused(const real d, const int allow_negative) {
  return !(d >= (real)0 || (allow_negative && d < (real)0)) || isinf(d);
}

// One item's share of volume_check: elements begin, begin + stride, … below end. Inlined with
// stride 1 (CPU devices: each item a contiguous chunk, which the compiler vectorises) and with
// the global size (GPUs: neighbouring items read neighbouring elements).
inline void check_range(__global const real* restrict v, const ulong begin, const ulong end,
                        const ulong stride, const int allow_negative, real* lo, real* hi,
                        ulong* first) {
  real a = *lo, b = *hi;
  bool any = false;
  for (ulong i = begin; i < end; i += stride) {
    const real d = v[i];
    any |= refused(d, allow_negative);
    a = fmin(a, d);  // fmin/fmax skip NaN
    b = fmax(b, d);
  }
  *lo = a, *hi = b;
  if (any)  // rare: find the first refused element again
    for (ulong i = begin; i < end; i += stride)
      if (refused(v[i], allow_negative)) {
        *first = i;
        break;
      }
}

// check_range over a contiguous chunk, 16 elements a step in vector registers (PoCL runs each
// work-item's loop as scalar code unless it is written in vectors: 4× faster at 512³).
#if IVR_F64
typedef double16 real16;
typedef long16 mask16;
#else
typedef float16 real16;
typedef int16 mask16;
#endif
inline void check_chunk(__global const real* restrict v, const ulong begin, const ulong end,
                        const int allow_negative, real* lo, real* hi, ulong* first) {
  real16 a = (real16)(*lo), b = (real16)(*hi);
  mask16 refusals = (mask16)(0);
  ulong i = begin;
  for (; i + 16 <= end; i += 16) {
    const real16 d = vload16(0, v + i);
    refusals |= isnan(d) | isinf(d) | (allow_negative ? (mask16)(0) : (d < (real16)(0)));
    a = fmin(a, d);
    b = fmax(b, d);
  }
  real lo16 = a.s0, hi16 = b.s0;
  for (int k = 1; k < 16; ++k) {  // the lanes, in order
    const real16 la = a, lb = b;
    lo16 = fmin(lo16, ((const real*)&la)[k]);
    hi16 = fmax(hi16, ((const real*)&lb)[k]);
  }
  *lo = lo16, *hi = hi16;
  ulong found = *first, tail = *first;
  if (any(refusals))  // rare: the first refused element of the vector part
    check_range(v, begin, i, 1, allow_negative, lo, hi, &found);
  check_range(v, i, end, 1, allow_negative, lo, hi, &tail);  // the last < 16 elements
  *first = min(found, tail);
}

// The check of a session's densities or target (one pass): per work-group the smallest and
// largest value and the first index holding one that is not finite — or negative, unless
// allow_negative (n where there is none). `chunk` > 0: item g checks [g·chunk, (g+1)·chunk);
// 0: grid-stride. The host reduces the groups' entries.
__kernel void volume_check(const ulong n, const ulong chunk, __global const real* restrict v,
                           const int allow_negative, __global real* restrict group_min,
                           __global real* restrict group_max, __global ulong* restrict group_bad) {
  __local real lo[IVR_REDUCE_SIZE], hi[IVR_REDUCE_SIZE];
  __local ulong bad[IVR_REDUCE_SIZE];
  const int lid = get_local_id(0);
  const ulong g = get_global_id(0);
  real a = (real)INFINITY, b = -(real)INFINITY;
  ulong first = n;
  if (chunk > 0)
    check_chunk(v, min(n, g * chunk), min(n, (g + 1) * chunk), allow_negative, &a, &b, &first);
  else
    check_range(v, g, n, get_global_size(0), allow_negative, &a, &b, &first);
  lo[lid] = a, hi[lid] = b, bad[lid] = first;
  for (int span = IVR_REDUCE_SIZE / 2; span > 0; span /= 2) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < span) {
      lo[lid] = fmin(lo[lid], lo[lid + span]);
      hi[lid] = fmax(hi[lid], hi[lid + span]);
      bad[lid] = min(bad[lid], bad[lid + span]);
    }
  }
  if (lid == 0) {
    const int group = get_group_id(0);
    group_min[group] = lo[0], group_max[group] = hi[0], group_bad[group] = bad[0];
  }
}

// Sums of rows, one work-group per block: out[b·cols + c] = Σ_{r < rows} in[(b·rows + r)·cols + c]
// — the adjoint's per-pixel terms (loss, background) into one row, the per-group camera partial
// sums into one row per view, the forward mode's per-group partial sums into one row (sum_rows:
// reals in), the loss's per-group partials (sum_acc_rows: sums in).
#define IVR_SUM_ROWS(name, type)                                                          \
  __kernel void name(__global const type* restrict in, const int rows, const int cols,  \
                     __global acc* restrict out) {                                        \
    __local acc scratch[IVR_REDUCE_SIZE];                                                 \
    const int lid = get_local_id(0), block = get_group_id(0);                             \
    __global const type* first = in + (size_t)block * rows * cols;                       \
    for (int c = 0; c < cols; ++c) {                                                      \
      acc s = (acc)0;                                                                     \
      for (int r = lid; r < rows; r += IVR_REDUCE_SIZE) s += (acc)first[(size_t)r * cols + c]; \
      scratch[lid] = s;                                                                   \
      group_sum(scratch, lid);                                                            \
      if (lid == 0) out[(size_t)block * cols + c] = scratch[0];                           \
    }                                                                                     \
  }
IVR_SUM_ROWS(sum_rows, real)
IVR_SUM_ROWS(sum_acc_rows, acc)

// The loss of an image against a target (docs/design.md's losses; kind 0 mse, 1 l1, 2 dot), per
// work-group partial sums of the elements' terms × norm (1 / elements; 1 for dot), grid-stride;
// sum_rows adds the groups' partials.
__kernel void loss_partial(const ulong n, __global const real* restrict image,
                           __global const real* restrict target, const acc norm, const int kind,
                           __global acc* restrict partial) {
  __local acc scratch[IVR_REDUCE_SIZE];
  const int lid = get_local_id(0);
  acc s = (acc)0;
  for (ulong i = get_global_id(0); i < n; i += get_global_size(0)) {
    const acc d = (acc)image[i] - (acc)target[i];
    s += kind == 2 ? (acc)image[i] * (acc)target[i] : kind == 1 ? fabs(d) : d * d;
  }
  scratch[lid] = s;
  group_sum(scratch, lid);
  if (lid == 0) partial[get_group_id(0)] = scratch[0] * norm;
}

// dst[i] = src[index[i]]: the listed voxels of a density gradient (group "voxels:LIST").
__kernel void gather(const int n, __global const real* restrict src,
                     __global const long* restrict index, __global real* restrict dst) {
  const int i = get_global_id(0);
  if (i < n) dst[i] = src[index[i]];
}

// A forward-mode gradient with a ray list's parameters (lib/jacobian/jacobian.cpp): dst[i] =
// per_ray[index[i]] (each ray's own derivatives, reals) where index[i] >= 0, else the other
// lanes' sums[−1 − index[i]].
__kernel void assemble(const ulong n, __global const real* restrict per_ray,
                       __global const acc* restrict sums, __global const long* restrict index,
                       __global acc* restrict dst) {
  const ulong i = get_global_id(0);
  if (i >= n) return;
  const long j = index[i];
  dst[i] = j >= 0 ? (acc)per_ray[j] : sums[-1 - j];
}

// Columns [src_first, src_first + count) of a rows × src_cols real matrix into columns
// [dst_first, …) of a rows × dst_cols one: a forward-mode pass's Jacobian lanes into the whole
// Jacobian.
__kernel void copy_columns(const ulong rows, __global const real* restrict src, const int src_cols,
                           const int src_first, __global real* restrict dst, const int dst_cols,
                           const int dst_first, const int count) {
  const ulong r = get_global_id(0);
  if (r >= rows) return;
  for (int c = 0; c < count; ++c)
    dst[r * dst_cols + dst_first + c] = src[r * src_cols + src_first + c];
}

#if IVR_ACC_F64
// Conversions between the two real types (only built where the device has float64).
__kernel void float_to_double(const ulong n, __global const float* restrict src,
                              __global double* restrict dst) {
  const ulong i = get_global_id(0);
  if (i < n) dst[i] = (double)src[i];
}

__kernel void double_to_float(const ulong n, __global const double* restrict src,
                              __global float* restrict dst) {
  const ulong i = get_global_id(0);
  if (i < n) dst[i] = (float)src[i];
}
#endif
