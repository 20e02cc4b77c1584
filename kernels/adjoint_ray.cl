// adjoint_ray.cl — what every integrator's adjoint march shares: the pixel's loss gradient and
// primal results, the per-sample gradient of a sample's density (into the voxels, the TF and the
// camera's sums), and the camera sums' conversion into dL / d camera.
#ifndef IVR_ADJOINT_RAY_CL
#define IVR_ADJOINT_RAY_CL
#include "adjoint_scatter.cl"
#include "config.cl"
#include "geometry.cl"
#include "jacobian_geometry.cl"
#include "march.cl"
#include "adjoint_tf.cl"

#ifndef IVR_GRAD_TF
#define IVR_GRAD_TF 0
#endif
#ifndef IVR_GRAD_CAMERA  // dL / d (eye, target, fov_y) per view
#define IVR_GRAD_CAMERA 0
#endif

// The pixel's loss gradient and what the primal march found (one ray's, or each lane's of a
// packet: kernels/rays.cl).
typedef struct {
  vreal gr, gg, gb, ga;             // dL / d pixel: emission–absorption RGB and alpha
  vreal gi;                         // absorption: dL / d I
  vreal total_r, total_g, total_b;  // the pixel's colour (emission–absorption)
  vreal intensity;                  // absorption: I
  vreal t_end;                      // transmittance where the march stopped
  vint end;                         // Radiance.end of the primal march
} AdjointRay;

// Where a ray's adjoint march stands: the prefix (transmittance and emission, summed exactly as the
// primal march summed C) before sample i (midpoint) or segment i (trapezoid, preintegrated); exact: i counts the pieces
// taken. In core a march starts at sample 0 with nothing in
// front; out of core (kernels/bricked_adjoint.cl) each brick goes on from where the one before
// left it. Carried with it, so that a ray's sums do not depend on where its march is cut: the
// ray's Σ |density contribution| so far (the fixed-point gradient's cap, checked once at the ray's
// end: adjoint_scatter.cl) and, for the endpoint schemes, what the sample the window ends on has
// collected from the segments before it (its scatter then happens once, in the next window, from
// all of its segments: adjoint_endpoints.cl).
typedef struct {
  vreal transmittance, pr, pg, pb, kr, kg, kb;
  vint i;
  vreal flushed;
  vreal gsigma, ger, geg, geb, gd;  // the open sample's sums (AdjointSample's)
} AdjointPrefix;

inline AdjointPrefix adjoint_prefix_begin(void) {
  AdjointPrefix p;
  p.transmittance = (vreal)(real)1;
  p.pr = p.pg = p.pb = p.kr = p.kg = p.kb = (vreal)(real)0;
  p.i = (vint)0;
  p.flushed = p.gsigma = p.ger = p.geg = p.geb = p.gd = (vreal)(real)0;
  return p;
}

// The camera gradient's sums over the ray (kernels/adjoint.cl turns them into dL / d camera):
// dL / d sample position and t · dL / d position, and dL / d of the ray's two end parameters
// through everything else that depends on them (segment layout, end points).
typedef struct {
  real gpx, gpy, gpz;
  real gtx, gty, gtz;
  real dldt0, dldt1;
  real t_end;    // the end parameter dldt1 is for: the box exit t1, or where an exact march stopped
  int end_axis;  // the centre plane's axis there, -1: the box
} CameraSums;

inline void camera_sums_init(CameraSums* s, real t1) {
  s->gpx = s->gpy = s->gpz = s->gtx = s->gty = s->gtz = s->dldt0 = s->dldt1 = (real)0;
  s->t_end = t1;
  s->end_axis = -1;
}

#if IVR_RAYS > 1 && IVR_GRAD_CAMERA
#error "the camera gradient marches one ray per work-item (lib/adjoint/adjoint.cpp)"
#endif

// dL/dd = gd at a sample at ray parameter t with fractions f in the current cell: into the
// cell's corners, and (camera) dL / d position = gd ∇d. Returns dL / d position · dir (how the
// loss moves when the sample slides along the ray).
#if IVR_RAYS == 1
__attribute__((always_inline)) inline real scatter_sample(CellCache* cell, real gd, real t, real fx,
                                                          real fy, real fz, real ux, real uy,
                                                          real uz, int4 dims, real4 inv_voxel,
                                                          real3 dir, CameraSums* cs) {
  cell_add(cell, gd, fx, fy, fz);
#if IVR_GRAD_CAMERA
  real ngx, ngy, ngz;
  trilinear_gradient(IVR_CELL_CORNERS(cell), fx, fy, fz, ux, uy, uz, dims, &ngx, &ngy, &ngz);
  const real px = gd * ngx * inv_voxel.x, py = gd * ngy * inv_voxel.y, pz = gd * ngz * inv_voxel.z;
  cs->gpx += px;
  cs->gpy += py;
  cs->gpz += pz;
  cs->gtx += t * px;
  cs->gty += t * py;
  cs->gtz += t * pz;
  return px * dir.x + py * dir.y + pz * dir.z;
#else
  (void)t, (void)ux, (void)uy, (void)uz, (void)dims, (void)inv_voxel, (void)dir, (void)cs;
  return (real)0;
#endif
}
#else
// A packet's lanes (no camera gradient: the position sums are one ray's).
__attribute__((always_inline)) inline vreal scatter_sample(CellCache* cell, vreal gd, vreal t,
                                                           vreal fx, vreal fy, vreal fz, vreal ux,
                                                           vreal uy, vreal uz, int4 dims,
                                                           real4 inv_voxel, real3 dir,
                                                           CameraSums* cs) {
  (void)t, (void)ux, (void)uy, (void)uz, (void)dims, (void)inv_voxel, (void)dir, (void)cs;
  cell_add(cell, gd, fx, fy, fz);
  return (vreal)(real)0;
}
#endif

#if IVR_RAYS == 1  // the camera gradient's: one ray per work-item
// For the fixed-step integrators: samples at t_i = t0 + (i + offset)·dt with dt = (t1 − t0)/n.
// `along` = Σ dL/d t_i, `indexed` = Σ (i + offset)·dL/d t_i, `direct` = dt · dL/d dt at fixed
// sample values (through each segment's length).
inline void fixed_step_ends(CameraSums* cs, const March* m, real along, real indexed, real direct) {
  const real dldt = direct / m->dt + indexed;  // dL / d dt
  cs->dldt1 = dldt / (real)m->n;
  cs->dldt0 = along - cs->dldt1;
}

// dL / d camera component k of this pixel from the sums: the ray's origin and direction
// adjoints, with t0 and t1 moving where a slab plane (or, for an exact march stopped early, a
// centre plane) sets them: t = (plane − o_a) / dir_a.
inline void camera_terms_of(const CameraSums* cs, Ray ray, real t0, real4 box_min, real4 box_max,
                            __global const real* camera_params, int width, int height, int x, int y,
                            real* terms) {
  real lo[3] = {cs->gpx, cs->gpy, cs->gpz}, ld[3] = {cs->gtx, cs->gty, cs->gtz};
  const int a0 = clip_axis(ray, box_min.xyz, box_max.xyz, t0, true);
  const real t1 = cs->t_end;
  const int a1 =
      cs->end_axis >= 0 ? cs->end_axis : clip_axis(ray, box_min.xyz, box_max.xyz, t1, false);
  if (a0 >= 0) {
    const real inv = (real)1 / component(ray.dir, a0);
    lo[a0] -= cs->dldt0 * inv;
    ld[a0] -= cs->dldt0 * t0 * inv;
  }
  if (a1 >= 0) {
    const real inv = (real)1 / component(ray.dir, a1);
    lo[a1] -= cs->dldt1 * inv;
    ld[a1] -= cs->dldt1 * t1 * inv;
  }
  const real sx = (real)2 * ((real)x + (real)0.5) / (real)width - (real)1;
  const real sy = (real)1 - (real)2 * ((real)y + (real)0.5) / (real)height;
  for (int k = 0; k < 7; ++k) {
    real3 o, d;
    camera_ray_tangent(camera_params, sx, sy, k, &o, &d);
    terms[k] = lo[0] * o.x + lo[1] * o.y + lo[2] * o.z + ld[0] * d.x + ld[1] * d.y + ld[2] * d.z;
  }
}

#endif  // IVR_RAYS == 1

#endif
