// private_sums.cl — the CPU adjoint's sums without atomics: work-groups of one work-item that take
// packets of rays from a shared counter, each adding into memory of its own; and the kernel that
// adds the density gradient's copies together.
//
// Why: OpenCL 1.2 has no float atomic add, and PoCL's CPU device runs the compare-and-swap loop
// kernels/atomics.cl writes as `lock cmpxchg`, 35 % of the packet adjoint's time at 128³ → 256²
// (docs/performance.md, "The adjoint in packets"), where a plain add takes a few cycles. OpenCL cannot say
// which thread runs a work-item, so "one copy of the gradient per thread" is built from what it
// can say: a work-group of one work-item is the only writer of its local memory and of any global
// memory indexed by its group id. The host launches as many such groups as the device has compute
// units (PoCL: worker threads; lib/adjoint/private_sums.hpp); they take chunks of packets in turn
// (small chunks, so that neighbouring tiles of like cost spread over every group; always the same
// chunks, so that the density gradient has the same bits on every call with as many compute
// units: -DIVR_PRIVATE_DYNAMIC takes them from a shared counter instead, which a thread slowed by
// another process helps less, measured within noise of the turns on 2 cores), add the TF
// gradient into their local accumulators and the density gradient into their own copies of the
// volume with plain adds. sum_private_copies() then adds the
// copies into the gradient (memory-bound, 16 values per work-item) and zeroes them, so that the
// next call finds them clean without a fill of its own.
//
// IVR_PRIVATE_SUMS (the host's, $IVR_PRIVATE_SUMS forces it): on, atomic_add_local() and the
// scatter sink's adds (kernels/atomics.cl, kernels/scatter_cache.cl) are plain adds. Not with the
// scatter cache (a table shared by a group's items), the camera gradient (per-item sums across a
// group) or the fixed-point gradient (its own atomics: they are integer adds, already exact).
#ifndef IVR_PRIVATE_SUMS_CL
#define IVR_PRIVATE_SUMS_CL
#include "config.cl"
#include "ivr_constants.h"

#ifndef IVR_PRIVATE_SUMS
#define IVR_PRIVATE_SUMS 0
#endif
#if IVR_PRIVATE_SUMS && (IVR_SCATTER_CACHE || IVR_GRAD_CAMERA || IVR_DETERMINISTIC)
#error IVR_PRIVATE_SUMS is for the float sums of the density and TF gradients alone
#endif

// Where copy `group` of a volume of `voxels` values begins: each copy padded to
// IVR_PRIVATE_ALIGN values (kernels/ivr_constants.h), so that sum_private_copies' vectors are
// aligned.
inline size_t private_copy_offset(int group, int voxels) {
  const size_t stride =
      ((size_t)voxels + IVR_PRIVATE_ALIGN - 1) / IVR_PRIVATE_ALIGN * IVR_PRIVATE_ALIGN;
  return (size_t)group * stride;
}

// Packets a work-group takes from the counter at once: few enough that the last ones spread over
// every group (at least 16 takes per group while there are enough packets), many enough that the
// counter's atomic is rare and a group marches neighbouring rays (their voxels in its cache).
inline int private_take_size(int packets) {
  return clamp(packets / (int)(get_num_groups(0) * 16), 1, 16);
}

// out[i] = Σ_g copies[g][i] in the order of g, and copies[g][i] = 0; IVR_PRIVATE_ALIGN values per
// work-item (PoCL runs a grid-stride loop as scalar code, a new cache line per element; vectors
// of contiguous values stream).
__kernel void sum_private_copies(const int voxels, const int copies, __global real* restrict parts,
                                 __global real* restrict out) {
  const size_t i = get_global_id(0) * IVR_PRIVATE_ALIGN;
  if (i >= (size_t)voxels) return;
  const size_t stride = private_copy_offset(1, voxels);
  if (i + IVR_PRIVATE_ALIGN <= (size_t)voxels) {
#if IVR_PRIVATE_ALIGN != 16
#error sum_private_copies reads 16 values at a time
#endif
#if IVR_F64
    typedef double16 real16;
#else
    typedef float16 real16;
#endif
    real16 sum = vload16(0, parts + i);
    vstore16((real16)(real)0, 0, parts + i);
    for (int g = 1; g < copies; ++g) {
      sum += vload16(0, parts + g * stride + i);
      vstore16((real16)(real)0, 0, parts + g * stride + i);
    }
    vstore16(sum, 0, out + i);
    return;
  }
  for (size_t j = i; j < (size_t)voxels; ++j) {  // the last, partial chunk
    real sum = parts[j];
    parts[j] = (real)0;
    for (int g = 1; g < copies; ++g) {
      sum += parts[g * stride + j];
      parts[g * stride + j] = (real)0;
    }
    out[j] = sum;
  }
}

#endif
