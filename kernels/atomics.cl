// atomics.cl — adding reals to global and local memory without losing updates: OpenCL 1.2 has no
// float atomics, so a compare-and-swap loop on the value's bits (32-bit, or 64-bit through
// cl_khr_int64_base_atomics for float64), unless the device has cl_ext_float_atomics or is
// NVIDIA's, whose native adds are reached through inline PTX (the host picks:
// lib/runtime/runtime.hpp, atomic_add_for).
#ifndef IVR_ATOMICS_CL
#define IVR_ATOMICS_CL
#include "config.cl"

#if IVR_F64
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
typedef ulong real_bits;
#define IVR_CMPXCHG atom_cmpxchg
#define as_real_bits as_ulong
#define as_real_value as_double
#else
typedef uint real_bits;
#define IVR_CMPXCHG atomic_cmpxchg
#define as_real_bits as_uint
#define as_real_value as_float
#endif

// IVR_FLOAT_ATOMICS (set by the host where the device reports cl_ext_float_atomics, and the
// program is built as OpenCL C 2.0 or later): the device's own atomic add, guarded by the
// compiler's feature macros so that a compiler without them still gets the CAS loop.
#ifndef IVR_FLOAT_ATOMICS
#define IVR_FLOAT_ATOMICS 0
#endif
#define IVR_NATIVE_GLOBAL_ADD 0
#define IVR_NATIVE_LOCAL_ADD 0
#if IVR_FLOAT_ATOMICS && IVR_F64
#define atomic_real atomic_double
#if defined(__opencl_c_ext_fp64_global_atomic_add)
#undef IVR_NATIVE_GLOBAL_ADD
#define IVR_NATIVE_GLOBAL_ADD 1
#endif
#if defined(__opencl_c_ext_fp64_local_atomic_add)
#undef IVR_NATIVE_LOCAL_ADD
#define IVR_NATIVE_LOCAL_ADD 1
#endif
#elif IVR_FLOAT_ATOMICS
#define atomic_real atomic_float
#if defined(__opencl_c_ext_fp32_global_atomic_add)
#undef IVR_NATIVE_GLOBAL_ADD
#define IVR_NATIVE_GLOBAL_ADD 1
#endif
#if defined(__opencl_c_ext_fp32_local_atomic_add)
#undef IVR_NATIVE_LOCAL_ADD
#define IVR_NATIVE_LOCAL_ADD 1
#endif
#endif

// IVR_PTX_ATOMICS (set by the host for NVIDIA's OpenCL, which compiles `asm` statements): the
// reduction red.global.add — no value returned, so no round trip — on sm_20 and later for
// float32, sm_60 for float64. 16.8 M adds into 1,024 floats on an H100: 0.84 ms against 126 ms by
// compare-and-swap (../shared/gpu/README.md; the statement is written as measured there).
// Local-memory adds keep the loop, which shared memory makes cheap there.
#ifndef IVR_PTX_ATOMICS
#define IVR_PTX_ATOMICS 0
#endif

inline void atomic_add_global(volatile __global real* p, real v) {
#if IVR_PTX_ATOMICS && IVR_F64
  asm volatile("red.global.add.f64 [%0], %1;" ::"l"(p), "d"(v) : "memory");
#elif IVR_PTX_ATOMICS
  asm volatile("red.global.add.f32 [%0], %1;" ::"l"(p), "f"(v) : "memory");
#elif IVR_NATIVE_GLOBAL_ADD
  atomic_fetch_add_explicit((volatile __global atomic_real*)p, v, memory_order_relaxed,
                            memory_scope_device);
#else
  volatile __global real_bits* bits = (volatile __global real_bits*)p;
  real_bits expected = as_real_bits(*p), seen;
  while ((seen = IVR_CMPXCHG(bits, expected, as_real_bits(as_real_value(expected) + v))) !=
         expected)
    expected = seen;
#endif
}

// With IVR_PRIVATE_SUMS every work-group is one work-item (kernels/private_sums.cl): its local
// memory is its own, and a plain add is exact.
inline void atomic_add_local(volatile __local real* p, real v) {
#if defined(IVR_PRIVATE_SUMS) && IVR_PRIVATE_SUMS
  *p += v;
#elif IVR_NATIVE_LOCAL_ADD
  atomic_fetch_add_explicit((volatile __local atomic_real*)p, v, memory_order_relaxed,
                            memory_scope_work_group);
#else
  volatile __local real_bits* bits = (volatile __local real_bits*)p;
  real_bits expected = as_real_bits(*p), seen;
  while ((seen = IVR_CMPXCHG(bits, expected, as_real_bits(as_real_value(expected) + v))) !=
         expected)
    expected = seen;
#endif
}

#endif
