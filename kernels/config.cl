// config.cl — feature switches and the `real` type; the host's generated preamble sets them, and
// these defaults let every kernel file compile on its own (e.g. offline with -I kernels).
#ifndef IVR_CONFIG_CL
#define IVR_CONFIG_CL

#define IVR_MODEL_ABSORPTION 0
#define IVR_MODEL_EMISSION_ABSORPTION 1

#define IVR_TF_IDENTITY 0
#define IVR_TF_PIECEWISE_LINEAR 1
#define IVR_TF_TABLE 2
#define IVR_TF_GAUSSIAN 3

// Integrators (ivr::Scheme, in its order).
#define IVR_SCHEME_MIDPOINT 0
#define IVR_SCHEME_TRAPEZOID 1
#define IVR_SCHEME_EXACT 2
#define IVR_SCHEME_PREINTEGRATED 3

#ifndef IVR_MODEL
#define IVR_MODEL IVR_MODEL_EMISSION_ABSORPTION
#endif
#ifndef IVR_SCHEME
#define IVR_SCHEME IVR_SCHEME_MIDPOINT
#endif
// Samples at segment ends (t0 + i·dt, i = 0..n) rather than midpoints.
#define IVR_ENDPOINT_SAMPLES \
  (IVR_SCHEME == IVR_SCHEME_TRAPEZOID || IVR_SCHEME == IVR_SCHEME_PREINTEGRATED)
#ifndef IVR_TF
#define IVR_TF IVR_TF_PIECEWISE_LINEAR
#endif
#ifndef IVR_F64
#define IVR_F64 0
#endif
#ifndef IVR_EARLY_TERMINATION  // 1: stop a ray once its transmittance < min_transmittance
#define IVR_EARLY_TERMINATION 1
#endif
#ifndef IVR_EMPTY_SPACE  // 1: jump over bricks whose σ is 0 everywhere (kernels/empty_space.cl)
#define IVR_EMPTY_SPACE 0
#endif
#ifndef IVR_RAY_LIST  // 1: the rays are a list (origin, direction, interval), not cameras' pixels
#define IVR_RAY_LIST 0
#endif
#ifndef IVR_BRICK_SIZE  // cells per brick edge of the occupancy grid
#define IVR_BRICK_SIZE 8
#endif

#if IVR_F64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double real;
typedef double3 real3;
typedef double4 real4;
#define convert_real3 convert_double3
#else
typedef float real;
typedef float3 real3;
typedef float4 real4;
#define convert_real3 convert_float3
#endif

#define IVR_EMISSION (IVR_MODEL == IVR_MODEL_EMISSION_ABSORPTION)
#if IVR_EMISSION
#define IVR_CHANNELS 4  // premultiplied RGB and alpha
#else
#define IVR_CHANNELS 1  // intensity
#endif

// a + (b - a)·t, written out so that it contracts into one fused multiply-add (OpenCL's default
// FP_CONTRACT); PoCL's mix() builtin is a separate multiply and add.
inline real lerp(real a, real b, real t) {
  return a + (b - a) * t;
}

// IVR_CAMERA_STRIDE and the other layouts the host shares.
#include "ivr_constants.h"

#endif
