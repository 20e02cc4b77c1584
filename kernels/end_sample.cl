// end_sample.cl — a sample at a segment end (t0 + i·dt) for the integrators that build each
// segment from its two ends: trapezoid (σ and the premultiplied emission) and preintegrated (the
// density alone: the segment integrates through the TF itself).
#ifndef IVR_END_SAMPLE_CL
#define IVR_END_SAMPLE_CL
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "tf.cl"

// One ray's, or every ray's of a packet (kernels/rays.cl).
typedef struct {
  vreal ux, uy, uz;  // voxel coordinates (empty-space skipping, gradients)
  vreal d;
  vreal sigma, er, eg, eb;  // trapezoid: σ and the emission σ·colour (preintegrated: unused)
} EndSample;

// Sample i of the march; *cursor: the TF search cursor, carried along the ray.
__attribute__((always_inline)) inline EndSample end_sample(__global const real* volume, int4 dims,
                                                           const March* m, vint i,
                                                           __global const real* tf, int tf_count,
                                                           real4 tf_scalars, vint* cursor) {
  EndSample s;
  const vreal t = sample_t(m, i);
  s.ux = IVR_POINT(m, t, x);
  s.uy = IVR_POINT(m, t, y);
  s.uz = IVR_POINT(m, t, z);
  s.d = trilinear_at(volume, dims, s.ux, s.uy, s.uz);
#if IVR_SCHEME == IVR_SCHEME_PREINTEGRATED
  // The segment integrates through the TF itself (kernels/preintegrated.cl).
  (void)tf, (void)tf_count, (void)tf_scalars, (void)cursor;
  s.sigma = s.er = s.eg = s.eb = (vreal)(real)0;
#else
  s.sigma = tf_sample(s.d, tf, tf_count, tf_scalars, cursor, &s.er, &s.eg, &s.eb);
#endif
  return s;
}

// *a = *b for the rays where m is true.
inline void end_sample_where(EndSample* a, const EndSample* b, vint m) {
  a->ux = vsel(a->ux, b->ux, m), a->uy = vsel(a->uy, b->uy, m), a->uz = vsel(a->uz, b->uz, m);
  a->d = vsel(a->d, b->d, m), a->sigma = vsel(a->sigma, b->sigma, m);
  a->er = vsel(a->er, b->er, m), a->eg = vsel(a->eg, b->eg, m), a->eb = vsel(a->eb, b->eb, m);
}

#endif
