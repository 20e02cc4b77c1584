/* ivr_constants.h — the numbers the host and the kernels must agree on (buffer layouts and codes),
 * written once and included by both: the kernels include it like any kernel file (embedded and
 * resolved once), lib/ from this folder. Preprocessor definitions only. */
#ifndef IVR_CONSTANTS_H
#define IVR_CONSTANTS_H

/* Values per view in the camera buffer (kernels/config.cl): eye, forward, right and up scaled to
 * the image plane (tan(fov/2)·aspect·right, tan(fov/2)·up' — or ortho half-extents), orthographic
 * flag; the rest is padding. */
#define IVR_CAMERA_STRIDE 16
/* Values per view in the camera-parameter buffer (kernels/jacobian_geometry.cl): eye, target, up,
 * fov_y (degrees), aspect (W/H), ortho_height, orthographic flag; the rest is padding. */
#define IVR_CAMERA_PARAMS_STRIDE 16
/* Values per ray of a ray list (IVR_RAY_LIST, kernels/geometry.cl), in the camera buffer's place:
 * origin, unit direction, t_start, t_end (world units along the direction; ±INFINITY: from the
 * box entry, to the box exit). */
#define IVR_RAY_STRIDE 8

/* Transfer-function rows (kernels/tf.cl):
 *   identity:          none; scalars = (extinction_scale, color_scale)
 *   piecewise_linear:  rows [density, r, g, b, sigma], sorted by density
 *   table:             rows [r, g, b, sigma]; scalars = (lo, hi)
 *   gaussian:          rows [mean, width, r, g, b, extinction] */
#define IVR_TF_STRIDE_PIECEWISE_LINEAR 5
#define IVR_TF_STRIDE_TABLE 4
#define IVR_TF_STRIDE_GAUSSIAN 6
/* Piecewise-linear and table TFs of at most IVR_TF_COLUMN_ENTRIES rows are followed by their
 * columns, each IVR_TF_COLUMN_ENTRIES values long (the last row repeated): density, r, g, b,
 * sigma (piecewise linear) or r, g, b, sigma (table). A packet of rays looks its rows up there
 * with one permute per column where the compiler has one (kernels/tf.cl, tf_rows; 16 rows for
 * 16 lanes, 8 for 8). */
#define IVR_TF_COLUMN_ENTRIES 16

/* What a tangent lane differentiates (int4 per lane: kind, a, b, c; kernels/jacobian_ray.cl). */
#define IVR_LANE_NONE 0       /* padding: derivative 0 */
#define IVR_LANE_TF 1         /* a = row, b = column */
#define IVR_LANE_BACKGROUND 2 /* a = channel */
#define IVR_LANE_CAMERA 3     /* a = view, b = component (0..6) */
#define IVR_LANE_VOXEL 4      /* (a, b, c) = (x, y, z) */
#define IVR_LANE_STEP 5       /* the step enters only through the sample count: derivative 0 */
#define IVR_LANE_RAY 6        /* a = column 0..7 of every listed ray's own row (IVR_RAY_LIST) */
/* Longs before the voxels in the deterministic (fixed-point) density gradient's buffer: the scale
 * exponent, the per-ray cap, the over-cap count, the largest contribution and the largest ray
 * (kernels/adjoint_scatter.cl). */
#define IVR_FIXED_HEADER 5

/* Values each private copy of the density gradient is padded to (kernels/private_sums.cl): one
 * 16-wide vector of the copies' sum. */
#define IVR_PRIVATE_ALIGN 16

/* Tangent lanes of one forward-mode pass at most (more parameters run in several passes). */
#define IVR_MAX_LANES 32

#endif
