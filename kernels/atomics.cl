// atomics.cl — adding reals to global and local memory without losing updates: OpenCL 1.2 has no
// float atomics, so a compare-and-swap loop on the value's bits (32-bit, or 64-bit through
// cl_khr_int64_base_atomics for float64).
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

inline void atomic_add_global(volatile __global real* p, real v) {
  volatile __global real_bits* bits = (volatile __global real_bits*)p;
  real_bits expected = as_real_bits(*p), seen;
  while ((seen = IVR_CMPXCHG(bits, expected, as_real_bits(as_real_value(expected) + v))) != expected)
    expected = seen;
}

inline void atomic_add_local(volatile __local real* p, real v) {
  volatile __local real_bits* bits = (volatile __local real_bits*)p;
  real_bits expected = as_real_bits(*p), seen;
  while ((seen = IVR_CMPXCHG(bits, expected, as_real_bits(as_real_value(expected) + v))) != expected)
    expected = seen;
}

#endif
