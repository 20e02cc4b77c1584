// adjoint_endpoints.cl — the adjoint march of the integrators that build each segment from its two
// end samples (trapezoid, preintegrated), front to back: each segment's remaining radiance is C
// minus the prefix (no division by 1 − α, no per-sample storage); a sample collects dL/d its
// density from the segments it ends and begins, and is scattered once both are done.
#ifndef IVR_ADJOINT_ENDPOINTS_CL
#define IVR_ADJOINT_ENDPOINTS_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (trapezoid)
#define IVR_SCHEME 1
#endif
#include "adjoint_ray.cl"
#include "compositing.cl"
#include "empty_space.cl"
#include "end_sample.cl"
#include "adjoint_preintegrated.cl"

// One ray per work-item: the adjoint marches packets for the midpoint rule only
// (lib/adjoint/adjoint.cpp, use_packet_adjoint).
#if IVR_RAYS == 1

// An end sample with what its scatter needs, and the gradient it has collected so far.
typedef struct {
  EndSample s;
  uint index;
  real t;
  real dsigma, der, deg, deb;  // trapezoid: dσ/dd and d(σ·colour)/dd
  real gsigma, ger, geg, geb;  // trapezoid: dL/dσ and dL/d(σ·colour) so far
  real gd;                     // preintegrated: dL/dd so far
} AdjointSample;

inline AdjointSample adjoint_sample(__global const real* volume, int4 dims, const March* m, uint i,
                                    __global const real* tf, int tf_count, real4 tf_scalars,
                                    int* cursor) {
  AdjointSample a;
  a.index = i;
  a.t = sample_t(m, i);
  a.gsigma = a.ger = a.geg = a.geb = a.gd = (real)0;
  a.dsigma = a.der = a.deg = a.deb = (real)0;
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
  // As end_sample(), with the slopes: tf_sample_slope() computes σ and the emission exactly as
  // tf_sample() does, so the march below recovers what the primal march rendered.
  a.s.ux = m->u0x + a.t * m->dux;
  a.s.uy = m->u0y + a.t * m->duy;
  a.s.uz = m->u0z + a.t * m->duz;
  a.s.d = trilinear_at(volume, dims, a.s.ux, a.s.uy, a.s.uz);
  TfPoint unused;
  a.s.sigma = tf_sample_slope(a.s.d, tf, tf_count, tf_scalars, cursor, &a.s.er, &a.s.eg, &a.s.eb,
                              &a.dsigma, &a.der, &a.deg, &a.deb, &unused);
#else
  a.s = end_sample(volume, dims, m, i, tf, tf_count, tf_scalars, cursor);
#endif
  return a;
}

// Sample a is complete: its dL/d density into the voxels (and the camera's sums), trapezoid's TF
// gradient into the work-group's accumulator.
inline void finish_sample(AdjointSample* a, CellCache* cell, __global const real* volume, int4 dims,
                          real4 inv_voxel, real3 dir, __global const real* tf, int tf_count,
                          real4 tf_scalars, int* cursor, const ScatterSink grad_volume,
                          TfGradCache* tf_cache, __local real* tf_acc, CameraSums* cs, real* along,
                          real* indexed) {
  real fx, fy, fz;
  const int ix = cell_axis(a->s.ux, dims.x, &fx), iy = cell_axis(a->s.uy, dims.y, &fy),
            iz = cell_axis(a->s.uz, dims.z, &fz);
  cell_enter(cell, ix, iy, iz, volume, dims, grad_volume, 1);
  const real gd =
      a->gd + a->gsigma * a->dsigma + a->ger * a->der + a->geg * a->deg + a->geb * a->deb;
  const real slide = scatter_sample(cell, gd, a->t, fx, fy, fz, a->s.ux, a->s.uy, a->s.uz, dims,
                                    inv_voxel, dir, cs);
  *along += slide;
  *indexed += (real)a->index * slide;
#if IVR_GRAD_TF && IVR_SCHEME == IVR_SCHEME_TRAPEZOID
  tf_scatter(a->s.d, tf, tf_count, tf_scalars, cursor, a->gsigma, a->ger, a->geg, a->geb, tf_cache,
             tf_acc);
#else
  (void)tf, (void)tf_count, (void)tf_scalars, (void)cursor, (void)tf_cache, (void)tf_acc;
#endif
}

inline void adjoint_march_endpoints(__global const real* volume, int4 dims, const March* m, Ray ray,
                                    real4 inv_voxel, __global const real* tf, int tf_count,
                                    real4 tf_scalars, const AdjointRay* ar,
                                    __global const uchar* occupied, int4 bricks,
                                    const ScatterSink grad_volume, TfGradCache* tf_cache,
                                    __local real* tf_acc, CameraSums* cs) {
  real transmittance = (real)1;
  real pr = 0, pg = 0, pb = 0;  // emission prefix, summed exactly as the primal march summed C
  real kr = 0, kg = 0, kb = 0;
  int seg_value = 0, seg_scatter = 0;
  CellCache cell;
  cell_init(&cell);
  real along = 0, indexed = 0, direct = 0;  // camera: fixed_step_ends()
  const real dt = m->dt;
  AdjointSample a = adjoint_sample(volume, dims, m, 0, tf, tf_count, tf_scalars, &seg_value);
  bool open = true;  // a still waits for its scatter
  for (uint i = 0; i < ar->end;) {
#if IVR_EMPTY_SPACE
    {
      const uint k = endpoint_skip(i, ar->end, a.s.ux, a.s.uy, a.s.uz, m, dims, occupied, bricks, vtrue);
      if (k > i) {  // the segments in between add nothing, nor does their gradient
        finish_sample(&a, &cell, volume, dims, inv_voxel, ray.dir, tf, tf_count, tf_scalars,
                      &seg_scatter, grad_volume, tf_cache, tf_acc, cs, &along, &indexed);
        open = false;
        i = k;
        if (i >= ar->end) break;
        a = adjoint_sample(volume, dims, m, i, tf, tf_count, tf_scalars, &seg_value);
        open = true;
      }
    }
#endif
    AdjointSample b = adjoint_sample(volume, dims, m, i + 1, tf, tf_count, tf_scalars, &seg_value);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    // τ = dt (σa + σb)/2, emission dt·fraction(τ)·(Ea + Eb)/2: as the primal's composite().
    const real tau = (real)0.5 * (a.s.sigma + b.s.sigma) * dt;
    real fraction;
    const real decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
    const real er = (real)0.5 * (a.s.er + b.s.er), eg = (real)0.5 * (a.s.eg + b.s.eg),
               eb = (real)0.5 * (a.s.eb + b.s.eb);
    const real weight = transmittance * dt * fraction;
    accumulate(&pr, &kr, weight * er);
    accumulate(&pg, &kg, weight * eg);
    accumulate(&pb, &kb, weight * eb);
    const real slope = transmittance * dt * fraction_slope(tau, decay, fraction);  // dweight/dτ
    const real gtau = ar->gr * (slope * er - (ar->total_r - pr)) +
                      ar->gg * (slope * eg - (ar->total_g - pg)) +
                      ar->gb * (slope * eb - (ar->total_b - pb)) + ar->ga * ar->t_end;
    const real ger = ar->gr * weight, geg = ar->gg * weight, geb = ar->gb * weight;
    direct += gtau * tau + ger * er + geg * eg + geb * eb;
    a.ger += (real)0.5 * ger, a.geg += (real)0.5 * geg, a.geb += (real)0.5 * geb;
    b.ger += (real)0.5 * ger, b.geg += (real)0.5 * geg, b.geb += (real)0.5 * geb;
#else
    const real gtau = -ar->intensity * ar->gi;
    direct += gtau * tau;
#endif
    transmittance = attenuate(transmittance, tau, fraction, decay);
    a.gsigma += (real)0.5 * dt * gtau;
    b.gsigma += (real)0.5 * dt * gtau;
#else
    preintegrated_segment_adjoint(&a.s, &b.s, dt, tf, tf_count, tf_scalars, ar, &transmittance, &pr,
                                  &pg, &pb, &kr, &kg, &kb, &a.gd, &b.gd, &direct, &seg_value,
                                  tf_cache, tf_acc);
#endif
    finish_sample(&a, &cell, volume, dims, inv_voxel, ray.dir, tf, tf_count, tf_scalars,
                  &seg_scatter, grad_volume, tf_cache, tf_acc, cs, &along, &indexed);
    a = b;
    open = true;
    ++i;
  }
  if (open)
    finish_sample(&a, &cell, volume, dims, inv_voxel, ray.dir, tf, tf_count, tf_scalars,
                  &seg_scatter, grad_volume, tf_cache, tf_acc, cs, &along, &indexed);
  cell_flush(&cell, grad_volume);
  fixed_step_ends(cs, m, along, indexed, direct);
}

#endif  // IVR_RAYS == 1
#endif
