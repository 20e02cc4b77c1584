/* ivr/ivr.h — the C API of ivr: opaque reference-counted handles, status codes, arrays as pointer
 * + shape + dtype. No exception and no C++ type crosses this boundary; every function returns an
 * ivr_status. Bindings (Python's ctypes, Julia, Rust, …) use this header.
 *
 * Ownership: every *_create / *_load / ivr_render-like call that outputs a handle gives the caller
 * one reference; release it with the matching *_release. Arrays passed in are copied before the
 * call returns (the caller keeps ownership); arrays out are written into caller-owned memory
 * whose size is given. Strings returned as const char* belong to the library and stay valid until
 * the next call on the same handle (or, for ivr_last_error, on the same thread).
 *
 * Threads: a context and everything created from it may be used by one thread at a time, with
 * one exception: sessions (below) of one context may be used from different threads at once.
 * Separate contexts may be used concurrently from separate threads. Handle bookkeeping (retain,
 * release, validation) is thread-safe; with several threads on one context read errors with
 * ivr_last_error (per thread), not ivr_context_last_error. */
#ifndef IVR_IVR_H
#define IVR_IVR_H
#include <stddef.h>
#include <stdint.h>

#include "ivr/export.h"
#include "ivr/version.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ivr's own codes are small positive numbers; OpenCL's (negative) are kept apart and reported by
 * ivr_last_opencl_error() when the status is IVR_ERROR_OPENCL. */
typedef enum ivr_status {
  IVR_OK = 0,
  IVR_ERROR_INVALID_ARGUMENT = 1,   /* bad scene, option, array, shape or dtype */
  IVR_ERROR_IO = 2,                 /* missing, unreadable or malformed file */
  IVR_ERROR_NO_DEVICE = 3,          /* no OpenCL platform, or no device matches */
  IVR_ERROR_OPENCL = 4,             /* an OpenCL call failed */
  IVR_ERROR_BUILD = 5,              /* a kernel failed to compile (the message has the build log) */
  IVR_ERROR_OUT_OF_MEMORY = 6,      /* host or device memory */
  IVR_ERROR_UNSUPPORTED = 7,        /* the device lacks a feature (e.g. float64) */
  IVR_ERROR_NULL_POINTER = 100,     /* a required pointer or handle is NULL */
  IVR_ERROR_INVALID_HANDLE = 101,   /* not a live handle of that type (released, or never one) */
  IVR_ERROR_WRONG_CONTEXT = 102,    /* handles from two different contexts */
  IVR_ERROR_BUFFER_TOO_SMALL = 103, /* an output array or string is smaller than the result */
  IVR_ERROR_INTERNAL = 199,         /* a bug: please report it with the message */
  IVR_STATUS_MAX_ENUM = 0x7fffffff
} ivr_status;

typedef enum ivr_dtype {
  IVR_FLOAT32 = 0,
  IVR_FLOAT64 = 1,
  IVR_UINT8 = 2,
  IVR_UINT16 = 3,
  IVR_DTYPE_MAX_ENUM = 0x7fffffff /* the enums span 32 bits so any int a binding passes is
                                     a defined value that the library rejects with a message */
} ivr_dtype;
typedef enum ivr_precision {
  IVR_PRECISION_F32 = 0,
  IVR_PRECISION_F64 = 1,
  IVR_PRECISION_MAX_ENUM = 0x7fffffff
} ivr_precision;
typedef enum ivr_mode {
  IVR_MODE_AUTO = 0,
  IVR_MODE_FORWARD = 1,
  IVR_MODE_ADJOINT = 2,
  IVR_MODE_MAX_ENUM = 0x7fffffff
} ivr_mode;
typedef enum ivr_loss {
  IVR_LOSS_MSE = 0,
  IVR_LOSS_L1 = 1,
  IVR_LOSS_DOT = 2, /* sum of target * image: the gradient is the vector-Jacobian product of the
                       render with the target as dL/dimage (an autograd backward), not a loss */
  IVR_LOSS_MAX_ENUM = 0x7fffffff
} ivr_loss;

typedef struct ivr_context ivr_context; /* a device, its queue and program cache, a last error */
typedef struct ivr_scene ivr_scene;     /* a scene with its volume (belongs to one context) */
typedef struct ivr_result ivr_result;   /* a gradient or Jacobian: loss, mode, named arrays */
typedef struct ivr_volume ivr_volume;   /* densities (nz, ny, nx) with their voxel spacing */
typedef struct ivr_transfer_function ivr_transfer_function; /* docs/design.md's "tf" object */

/* Static name of a status, e.g. "IVR_ERROR_INVALID_ARGUMENT". Never NULL. */
IVR_API const char* ivr_status_string(ivr_status status);
/* The library's version (the header's is IVR_VERSION_*): major*10000 + minor*100 + patch. */
IVR_API int ivr_version(void);
/* The last error message of this thread (any call), "" if none. */
IVR_API const char* ivr_last_error(void);
/* The OpenCL error code behind this thread's last IVR_ERROR_OPENCL, else 0. */
IVR_API int ivr_last_opencl_error(void);

/* Every OpenCL device as a JSON document ({"devices": [...]}, the fields of `ivr devices
 * --json`), written into `buffer` (capacity bytes, NUL-terminated); *needed gets the size with
 * the NUL (may be NULL). A NULL buffer with capacity 0 only reports the size. */
IVR_API ivr_status ivr_devices_json(char* buffer, size_t capacity, size_t* needed);

/* A context on a device: selector as for `--device` (NULL or "": $IVR_DEVICE, else the first
 * GPU, else the first device). */
IVR_API ivr_status ivr_context_create(const char* device_selector, ivr_context** context);
IVR_API ivr_status ivr_context_retain(ivr_context* context);
IVR_API ivr_status ivr_context_release(ivr_context* context);
/* The context's last error message ("" if none); valid until the next call on the context. */
IVR_API const char* ivr_context_last_error(const ivr_context* context);
/* The device's name (library-owned string, valid while the context lives). */
IVR_API ivr_status ivr_context_device_name(const ivr_context* context, const char** name);

/* A scene from docs/design.md's JSON text; relative volume paths resolve against base_dir (NULL: the
 * working folder). The JSON may leave out "volume" when ivr_scene_set_volume follows. */
IVR_API ivr_status ivr_scene_from_json(ivr_context* context, const char* json, const char* base_dir,
                                       ivr_scene** scene);
/* A scene from a JSON file. */
IVR_API ivr_status ivr_scene_load(ivr_context* context, const char* path, ivr_scene** scene);
IVR_API ivr_status ivr_scene_retain(ivr_scene* scene);
IVR_API ivr_status ivr_scene_release(ivr_scene* scene);
/* Replaces the scene's volume by a copy of `data`: shape (nz, ny, nx), x fastest (C order);
 * float32/float64 used as is, uint8/uint16 mapped to [0, 1] by the type's range. The box is reset
 * to the default (centred, longest side 1) unless the scene's JSON gave one. */
IVR_API ivr_status ivr_scene_set_volume(ivr_scene* scene, const void* data, ivr_dtype dtype,
                                        const int64_t shape[3]);
/* Worker `rank` of `ranks`' slab of a volume of `nz` planes: replaces the scene's volume by a copy
 * of `data`, shape (planes, ny, nx) — planes ivr_domain_slab(nz, rank, ranks) of the whole
 * (nz, ny, nx) volume, so that a worker over slabs never holds the rest (dtypes as
 * ivr_scene_set_volume; the box the whole volume's). Such a scene serves only that worker's
 * operations over slabs and segments — ivr_render_split, ivr_gradient_split,
 * ivr_reconstruction_create_split, with the same rank and ranks —; the others refuse it by name.
 * ivr_scene_set_volume makes the scene whole again. */
IVR_API ivr_status ivr_scene_set_volume_slab(ivr_scene* scene, const void* data, ivr_dtype dtype,
                                             const int64_t shape[3], int64_t nz, int rank,
                                             int ranks);
/* The same for the weighted slabs (`shares`: `ranks` weights, NULL: equal): `data` holds planes
 * ivr_domain_slab_weighted(nz, rank, ranks, shares); the scene serves ivr_render_split_weighted,
 * ivr_gradient_split_weighted and ivr_reconstruction_create_weighted with the same shares. */
IVR_API ivr_status ivr_scene_set_volume_slab_weighted(ivr_scene* scene, const void* data,
                                                      ivr_dtype dtype, const int64_t shape[3],
                                                      int64_t nz, int rank, int ranks,
                                                      const double* shares);
/* Volumes and transfer functions of their own, made once and set on any scene of the context
 * (the scene takes a copy: later changes to one do not reach the other). */
/* A volume from caller memory, copied (dtypes as ivr_scene_set_volume), spacing 1. */
IVR_API ivr_status ivr_volume_create(ivr_context* context, const void* data, ivr_dtype dtype,
                                     const int64_t shape[3], ivr_volume** volume);
/* A volume from docs/design.md's "volume" object, e.g. {"file": "head.nrrd"} or {"synthetic":
 * "sphere", "dims": [32, 32, 32]}; relative paths resolve against base_dir (NULL: working folder).
 */
IVR_API ivr_status ivr_volume_from_json(ivr_context* context, const char* json,
                                        const char* base_dir, ivr_volume** volume);
IVR_API ivr_status ivr_volume_retain(ivr_volume* volume);
IVR_API ivr_status ivr_volume_release(ivr_volume* volume);
/* (nz, ny, nx) */
IVR_API ivr_status ivr_volume_shape(const ivr_volume* volume, int64_t shape[3]);
/* The densities as float32, x fastest, into caller memory of `capacity` floats. */
IVR_API ivr_status ivr_volume_data(const ivr_volume* volume, float* values, size_t capacity);
/* Copies the volume (with its spacing) into the scene; the box as for ivr_scene_set_volume. */
IVR_API ivr_status ivr_scene_set_volume_handle(ivr_scene* scene, const ivr_volume* volume);
/* A transfer function from docs/design.md's "tf" object, checked as in a scene. */
IVR_API ivr_status ivr_tf_from_json(ivr_context* context, const char* json,
                                    ivr_transfer_function** tf);
IVR_API ivr_status ivr_tf_retain(ivr_transfer_function* tf);
IVR_API ivr_status ivr_tf_release(ivr_transfer_function* tf);
/* Copies the transfer function into the scene, replacing its own. */
IVR_API ivr_status ivr_scene_set_tf(ivr_scene* scene, const ivr_transfer_function* tf);

/* A ray list instead of the scene's cameras (docs/design.md, "Ray lists"): `rows` rows of
 * `columns` doubles, row-major — 8 (ox oy oz dx dy dz t_start t_end; t_start may be -INFINITY,
 * t_end INFINITY) or 6 (start and end points). Checked (the first bad ray and field named) and
 * copied; the scene's cameras are dropped. Images are then one value per ray (shape (1, 1, rows,
 * channels) below; the bindings show (rows, channels)). */
IVR_API ivr_status ivr_scene_set_rays(ivr_scene* scene, const double* values, size_t rows,
                                      int columns);
/* The number of rays of the scene's ray list (0: the scene has cameras). */
IVR_API ivr_status ivr_scene_ray_count(const ivr_scene* scene, size_t* rays);

/* The shape of the scene's images: (views, height, width, channels); a ray list's (1, 1, rays,
 * channels). */
IVR_API ivr_status ivr_scene_image_shape(const ivr_scene* scene, int64_t shape[4]);
/* The volume's shape (nz, ny, nx). */
IVR_API ivr_status ivr_scene_volume_shape(const ivr_scene* scene, int64_t shape[3]);

/* The integrator step (voxel units) a render of the scene uses: the scene's own, or, where its
 * integrator asks for a "tolerance", the step chosen for it (pilot renders at a quarter of the
 * resolution, Richardson: docs/integrators.md); *estimated_error (may be NULL) receives that
 * step's estimated relative RMS error (0 without a tolerance). Renders with step 0 use this step.
 */
IVR_API ivr_status ivr_scene_step(ivr_context* context, const ivr_scene* scene,
                                  ivr_precision precision, double* step, double* estimated_error);

/* Renders every view into `image`: float32, shape ivr_scene_image_shape, `capacity` floats. step
 * > 0 overrides the scene's integrator step and tolerance (voxel units). */
IVR_API ivr_status ivr_render(ivr_context* context, const ivr_scene* scene, ivr_precision precision,
                              double step, float* image, size_t capacity);

/* The loss of the render against `target` (float32, the image shape; `count` floats) and its
 * gradient with respect to the comma-separated groups in `wrt` (as `ivr gradient --wrt`: density,
 * tf, tf_points, scales, background, camera, step, voxels:LIST), in `mode`. */
IVR_API ivr_status ivr_gradient(ivr_context* context, const ivr_scene* scene, const float* target,
                                size_t count, const char* wrt, ivr_mode mode, ivr_loss loss,
                                ivr_precision precision, double step, ivr_result** result);
/* Worker-shared (split) gradients, renders, tomography and reconstructions: ivr/ivr_split.h. */
/* The loss (mean over every element: IVR_LOSS_MSE of the squared, IVR_LOSS_L1 of the absolute
 * differences) of `image` against `target`, both `count` floats. */
IVR_API ivr_status ivr_image_loss(const float* image, const float* target, size_t count,
                                  ivr_loss loss, double* value);
/* The Jacobian (views, H, W, C, P) of the render with respect to `wrt` (forward mode), as one
 * array named "jacobian" in the result. */
IVR_API ivr_status ivr_jacobian(ivr_context* context, const ivr_scene* scene, const char* wrt,
                                ivr_precision precision, double step, ivr_result** result);
IVR_API ivr_status ivr_result_retain(ivr_result* result);
IVR_API ivr_status ivr_result_release(ivr_result* result);
/* The loss (0 for a Jacobian), the mode that ran, and the kernel seconds. */
IVR_API ivr_status ivr_result_info(const ivr_result* result, double* loss, ivr_mode* mode,
                                   double* seconds);
/* The result's arrays: their count, and array i's name (library-owned), rank and shape (up to 5
 * dimensions) and values (float64, `capacity` elements). */
IVR_API ivr_status ivr_result_array_count(const ivr_result* result, size_t* count);
IVR_API ivr_status ivr_result_array_shape(const ivr_result* result, size_t index, const char** name,
                                          int* rank, int64_t shape[5]);
IVR_API ivr_status ivr_result_array_data(const ivr_result* result, size_t index, double* values,
                                         size_t capacity);

/* --- Absorption tomography: log(I / I_in) = -N v (c_api_tomo.cpp) ----------------------------
 * The rays are the cameras' pixel rays ordered (view, y, x): views * height * width of them (the
 * image shape with one channel); the grid is the scene volume's (nz, ny, nx) in its box.
 * (N v)[ray] is the integral of the trilinear volume along the ray (world units), evaluated
 * exactly whatever the scene's integrator; the model and TF are not used. Inputs must be finite. */

/* Line integrals N v into `lines` (`capacity` floats >= the ray count). `volume` (`count` floats
 * = nz * ny * nx, x fastest) stands in for the scene's densities; NULL: the scene's own (`count`
 * is then ignored). */
IVR_API ivr_status ivr_project(ivr_context* context, const ivr_scene* scene,
                               ivr_precision precision, const float* volume, size_t count,
                               float* lines, size_t capacity);
/* The exact transpose of ivr_project, N^T p: `lines` (`count` floats = the ray count) onto the
 * scene's grid, into `volume` (`capacity` floats >= nz * ny * nx). */
IVR_API ivr_status ivr_backproject(ivr_context* context, const ivr_scene* scene,
                                   ivr_precision precision, const float* lines, size_t count,
                                   float* volume, size_t capacity);

typedef enum ivr_solver {
  IVR_SOLVER_CGLS = 0,
  IVR_SOLVER_SIRT = 1,
  IVR_SOLVER_LSQR = 2,
  IVR_SOLVER_MAX_ENUM = 0x7fffffff
} ivr_solver;

/* What ivr_tomo solves: min 1/2 |N x - p|^2 (SIRT: row-normalised) + an optional regulariser,
 * optionally x >= 0. Fill it with ivr_tomo_options_init, then change fields. */
typedef struct ivr_tomo_options {
  size_t size;             /* sizeof the struct, set by the init function (it may grow) */
  ivr_solver solver;       /* IVR_SOLVER_CGLS */
  ivr_precision precision; /* IVR_PRECISION_F32 */
  int iterations;          /* 50: the most iterations, >= 1 */
  int nonneg;              /* 0; non-zero: project onto x >= 0 after every iteration */
  int tv_reweight;         /* 10: CGLS/LSQR iterations between TV re-weightings, >= 1 */
  double tolerance;        /* 0; > 0: stop once |p - N x| / |p| <= tolerance */
  double tikhonov;         /* 0: lambda >= 0 of lambda/2 |x|^2 */
  double tv;               /* 0: lambda >= 0 of the smoothed TV (not with tikhonov) */
  double tv_epsilon;       /* 1e-3: the TV's smoothing epsilon, > 0 */
  double relaxation;       /* 1: SIRT's omega in (0, 2) */
} ivr_tomo_options;
/* The defaults above. */
IVR_API ivr_status ivr_tomo_options_init(ivr_tomo_options* options);

/* One completed iteration: its number (from 1), |p - N x| / |p| (0 when p = 0), and the wall
 * seconds since the solver started. */
typedef struct ivr_tomo_iteration {
  int iteration;
  double residual;
  double seconds;
} ivr_tomo_iteration;
/* Called after every iteration with `user`; return 0 to stop (the last iterate is the result,
 * stop reason "interrupted"), non-zero to go on. It must not call ivr on the same context. */
typedef int (*ivr_tomo_progress)(const ivr_tomo_iteration* iteration, void* user);

typedef struct ivr_tomo_summary {
  int iterations;          /* completed iterations */
  const char* stop_reason; /* static: "iterations", "tolerance", "converged" or "interrupted" */
  double residual;         /* the last iteration's (0 if none ran) */
  double seconds;          /* solver wall time (after the setup) */
  double setup_seconds;    /* compiling, uploads, SIRT's normalisations */
} ivr_tomo_summary;

/* Reconstructs the scene's grid from line integrals `lines` (`count` floats = the ray count)
 * into `volume` (`capacity` floats >= nz * ny * nx), starting from zeros. options: NULL for the
 * defaults. progress (may be NULL) is called with `user` after every iteration. history (may be
 * NULL with history_capacity 0; else history_capacity >= options->iterations) receives one entry
 * per completed iteration; summary (may be NULL) how it ended. Stopped by the callback, the call
 * still succeeds. */
IVR_API ivr_status ivr_tomo(ivr_context* context, const ivr_scene* scene,
                            const ivr_tomo_options* options, const float* lines, size_t count,
                            float* volume, size_t capacity, ivr_tomo_progress progress, void* user,
                            ivr_tomo_iteration* history, size_t history_capacity,
                            ivr_tomo_summary* summary);




/* Line integrals from intensities, p = -log(I / I_in) / a (I_in: the scene's background, a: its
 * identity TF's extinction_scale; other TFs are refused): `count` floats = the ray count into
 * `lines` (`capacity` floats). I <= 0 is an error unless clamp in (0, 1): then I is raised to
 * clamp * I_in first. */
IVR_API ivr_status ivr_lines_from_intensities(const ivr_scene* scene, const float* intensities,
                                              size_t count, double clamp, float* lines,
                                              size_t capacity);

/* A tomography test volume of shape (n, n, n), n in 1..1024, sampled at the voxel centres of
 * [-1, 1]^3 into `volume` (`capacity` floats >= n^3): name "shepp-logan" (3D Shepp-Logan of Kak
 * & Slaney) or "ellipsoids" (10 random ellipsoids from `seed`, the same on every platform).
 * supersample s in 1..16: each voxel the mean of s^3 samples at its sub-cell centres (1: the
 * voxel centre). */
IVR_API ivr_status ivr_phantom(const char* name, int n, uint64_t seed, int supersample,
                               float* volume, size_t capacity);

/* --- Reconstruction and viewpoint selection (c_api_reconstruct.cpp) ---------------------------
 * Inverse rendering: the voxel densities, the transfer function or both recovered from images of
 * the scene's cameras, one iteration at a time (coarse to fine, random view batches, priors),
 * with checkpoints; and the camera on an orbit whose image has the highest entropy. */

typedef enum ivr_optimizer {
  IVR_OPTIMIZER_AUTO = 0, /* adam; lbfgs when only the TF is optimised (viewpoints: adam) */
  IVR_OPTIMIZER_ADAM = 1,
  IVR_OPTIMIZER_SGD = 2,   /* with momentum; needs an explicit lr */
  IVR_OPTIMIZER_LBFGS = 3, /* small parameter sets only (TF, viewpoint), every view per step */
  IVR_OPTIMIZER_MAX_ENUM = 0x7fffffff
} ivr_optimizer;
/* The learning rate of 0-based iteration k: constant lr; step lr * gamma^floor(k / step_every);
 * cosine min_lr + (lr - min_lr) * (1 + cos(pi k / K)) / 2 over K = the level's iterations (the
 * TF alone: all of them). */
typedef enum ivr_schedule {
  IVR_SCHEDULE_CONSTANT = 0,
  IVR_SCHEDULE_STEP = 1,
  IVR_SCHEDULE_COSINE = 2,
  IVR_SCHEDULE_MAX_ENUM = 0x7fffffff
} ivr_schedule;
/* Where the densities start: the scene's volume, zeros (absorption scenes only: zero densities
 * are a stationary point of emission-absorption), or init_value everywhere. */
typedef enum ivr_init {
  IVR_INIT_SCENE = 0,
  IVR_INIT_ZEROS = 1,
  IVR_INIT_CONSTANT = 2,
  IVR_INIT_MAX_ENUM = 0x7fffffff
} ivr_init;

/* What a reconstruction optimises and how. Fill it with ivr_reconstruct_options_init, then
 * change fields; ranges are checked by ivr_reconstruction_create, naming the field. */
typedef struct ivr_reconstruct_options {
  size_t size;             /* sizeof the struct, set by the init function (it may grow) */
  int density;             /* 1: optimise every voxel (adjoint mode) */
  int tf;                  /* 0: optimise the TF's parameters (rows as ivr_reconstruction_tf) */
  int iterations;          /* 300: in total, over every level, >= 1 */
  ivr_optimizer optimizer; /* IVR_OPTIMIZER_AUTO */
  double lr;               /* 0: automatic (adam 0.025, lbfgs 0.05; sgd needs one), else > 0 */
  ivr_schedule schedule;   /* IVR_SCHEDULE_CONSTANT */
  int step_every;          /* 100: iterations per factor of the step schedule */
  double step_gamma;       /* 0.5: the step schedule's factor, in (0, 1] */
  double min_lr;           /* 0: the cosine schedule's floor, in [0, lr] */
  ivr_loss loss;           /* IVR_LOSS_MSE */
  double tv;               /* 0: weight of the smoothed total variation of the densities */
  double smoothness;       /* 0: weight of the mean squared density gradient */
  double tf_smoothness;    /* 0: weight of the squared differences of consecutive TF rows */
  double tv_epsilon;       /* 0.01: the TV's smoothing, > 0 */
  int batch;               /* 0: views per iteration drawn at random (0: every view) */
  int levels;              /* 0: coarse-to-fine levels, 0..8 (0: 3 where the grid allows) */
  ivr_init init;           /* IVR_INIT_SCENE */
  double init_value;       /* 0.5: the density of IVR_INIT_CONSTANT, >= 0 */
  uint64_t seed;           /* 1: of the view batches */
  ivr_precision precision; /* IVR_PRECISION_F32 */
  double step;             /* 0; > 0 overrides the scene's integrator step (voxel units) */
  ivr_mode mode;           /* IVR_MODE_AUTO: forward or adjoint for the TF alone */
} ivr_reconstruct_options;
/* The defaults above (the C++ core's). */
IVR_API ivr_status ivr_reconstruct_options_init(ivr_reconstruct_options* options);

/* One completed iteration: its number (from 1, over all levels), level (0 = the coarsest), the
 * image loss of its batch at its start and the priors' value there, the learning rate used
 * (L-BFGS: its initial step), its wall seconds and the views in its batch. */
typedef struct ivr_reconstruct_iteration {
  int iteration;
  int level;
  double loss;
  double prior;
  double lr;
  double seconds;
  int views;
} ivr_reconstruct_iteration;
/* Called after every iteration of ivr_reconstruction_run with `user`; return 0 to stop, non-zero
 * to go on. It must not call ivr on the same context. */
typedef int (*ivr_reconstruct_progress)(const ivr_reconstruct_iteration* iteration, void* user);

typedef struct ivr_reconstruct_summary {
  int iterations;          /* completed iterations in total (a resumed run counts the earlier) */
  int steps;               /* iterations this call ran */
  const char* stop_reason; /* static: "done" or "interrupted" */
  double loss;             /* the last iteration's loss (0 if none ran) */
  double seconds;          /* this call's wall time */
} ivr_reconstruct_summary;

/* The state of a reconstruction, with what "automatic" resolved to. */
typedef struct ivr_reconstruct_info {
  int iteration;           /* completed iterations */
  int iterations;          /* in total */
  int levels;              /* coarse-to-fine levels */
  ivr_optimizer optimizer; /* the optimiser in use (never AUTO) */
  double lr;               /* its base learning rate */
} ivr_reconstruct_info;

/* A reconstruction of `scene` (its volume gives the grid and, with IVR_INIT_SCENE, the start;
 * its TF the known or starting TF) from `targets`: float32 in the scene's image shape, `count`
 * floats, finite. options: NULL for the defaults. Nothing runs until a step; the scene and
 * targets are copied, and the handle keeps its context alive. */
typedef struct ivr_reconstruction ivr_reconstruction;
IVR_API ivr_status ivr_reconstruction_create(ivr_context* context, const ivr_scene* scene,
                                             const float* targets, size_t count,
                                             const ivr_reconstruct_options* options,
                                             ivr_reconstruction** reconstruction);
IVR_API ivr_status ivr_reconstruction_retain(ivr_reconstruction* reconstruction);
IVR_API ivr_status ivr_reconstruction_release(ivr_reconstruction* reconstruction);
/* One iteration; `iteration` (may be NULL) receives its record. IVR_ERROR_INVALID_ARGUMENT once
 * done. */
IVR_API ivr_status ivr_reconstruction_step(ivr_reconstruction* reconstruction,
                                           ivr_reconstruct_iteration* iteration);
/* Iterations until done or until `progress` (may be NULL) returns 0; summary may be NULL.
 * Stopped by the callback, the call still succeeds and later steps continue the run. */
IVR_API ivr_status ivr_reconstruction_run(ivr_reconstruction* reconstruction,
                                          ivr_reconstruct_progress progress, void* user,
                                          ivr_reconstruct_summary* summary);
/* *done = 1 once every iteration has run, else 0. */
IVR_API ivr_status ivr_reconstruction_done(const ivr_reconstruction* reconstruction, int* done);
IVR_API ivr_status ivr_reconstruction_info(const ivr_reconstruction* reconstruction,
                                           ivr_reconstruct_info* info);
/* Level `level`'s grid, (nz, ny, nx). */
IVR_API ivr_status ivr_reconstruction_level_shape(const ivr_reconstruction* reconstruction,
                                                  int level, int64_t shape[3]);
/* The completed iterations' records (restored ones included after a resume): *count gets their
 * number (may be NULL); up to `capacity` are written to `history` (NULL with capacity 0: count
 * only). */
IVR_API ivr_status ivr_reconstruction_history(const ivr_reconstruction* reconstruction,
                                              ivr_reconstruct_iteration* history, size_t capacity,
                                              size_t* count);
/* The current densities at the scene's full grid (upsampled from a coarser level; the scene's
 * own volume when only the TF is optimised): float32, x fastest, into `volume` (`capacity`
 * floats); shape (may be NULL) gets (nz, ny, nx). NULL volume with capacity 0: the shape only. */
IVR_API ivr_status ivr_reconstruction_volume(const ivr_reconstruction* reconstruction,
                                             float* volume, size_t capacity, int64_t shape[3]);
/* The current TF's parameters, rows x columns in the layout of its gradient (docs/design.md: one row
 * per control point / table entry [r, g, b, extinction], Gaussian [r, g, b, extinction, mean,
 * width], identity one row [extinction_scale, color_scale]): float64 into `values` (`capacity`),
 * shape (may be NULL) gets (rows, columns). NULL values with capacity 0: the shape only. */
IVR_API ivr_status ivr_reconstruction_tf(const ivr_reconstruction* reconstruction, double* values,
                                         size_t capacity, int64_t shape[2]);
/* The estimate as a new scene of the same context: the current densities (full grid) and TF. */
IVR_API ivr_status ivr_reconstruction_result_scene(const ivr_reconstruction* reconstruction,
                                                   ivr_scene** scene);
/* PREFIX_checkpoint.json and PREFIX_checkpoint_*.npy (the folder must exist); each file replaced
 * atomically. */
IVR_API ivr_status ivr_reconstruction_save_checkpoint(const ivr_reconstruction* reconstruction,
                                                      const char* prefix);
/* Continues from a checkpoint written with the same scene grid, targets' shape and options (the
 * message names the first that differs); the history is restored with it. */
IVR_API ivr_status ivr_reconstruction_resume(ivr_reconstruction* reconstruction,
                                             const char* prefix);

/* Viewpoint selection: gradient ascent of the entropy of view `view`'s image over the camera's
 * orbit about its target (azimuth about its up axis, elevation within +-85 degrees, distance
 * kept), derivatives in forward mode. */
typedef struct ivr_viewpoint_options {
  size_t size;             /* sizeof the struct, set by the init function (it may grow) */
  int view;                /* 0: the scene's camera to start from */
  int iterations;          /* 40: >= 0 (0: the start's entropy only) */
  ivr_optimizer optimizer; /* IVR_OPTIMIZER_AUTO (adam); sgd or lbfgs */
  double lr;               /* 0: 0.05 radians per step, else > 0 */
  ivr_precision precision; /* IVR_PRECISION_F32 */
  double step;             /* 0; > 0 overrides the scene's integrator step (voxel units) */
} ivr_viewpoint_options;
IVR_API ivr_status ivr_viewpoint_options_init(ivr_viewpoint_options* options);

/* An iterate of the ascent: number (0 = the start), its entropy and orbit angles (degrees). */
typedef struct ivr_viewpoint_step {
  int iteration;
  double entropy;
  double azimuth;
  double elevation;
} ivr_viewpoint_step;
/* Called with every iterate (the start included); return 0 to stop. It must not call ivr on the
 * same context. */
typedef int (*ivr_viewpoint_progress)(const ivr_viewpoint_step* step, void* user);

/* A camera as docs/design.md's JSON object has it. */
typedef struct ivr_camera {
  double eye[3];
  double target[3];
  double up[3];
  double fov_y;        /* degrees (perspective) */
  int orthographic;    /* non-zero: "projection": "orthographic" */
  double ortho_height; /* world units (orthographic) */
  int width;
  int height;
} ivr_camera;

typedef struct ivr_viewpoint_result {
  ivr_camera camera;    /* the best camera seen (highest entropy) */
  double entropy_start; /* of the starting camera */
  double entropy_best;  /* of `camera`, >= entropy_start */
  int iterations;       /* completed iterations (the start not counted) */
} ivr_viewpoint_result;

/* The camera of the highest image entropy found (ivr_image_entropy) into *result. history (may
 * be NULL with history_capacity 0; else history_capacity >= options->iterations + 1) receives
 * every iterate from the start. Stopped by the callback, the call still succeeds. */
IVR_API ivr_status ivr_select_viewpoint(ivr_context* context, const ivr_scene* scene,
                                        const ivr_viewpoint_options* options,
                                        ivr_viewpoint_progress progress, void* user,
                                        ivr_viewpoint_step* history, size_t history_capacity,
                                        ivr_viewpoint_result* result);

/* Normalised entropy in [0, 1] of view 0 of `image` (float32, shape (views, H, W, C), C = 1 or 4):
 * brightness q (emission-absorption: mean of R, G, B; absorption: 1 - I / background) + 1e-6,
 * p = q / sum q, H = -sum p ln p / ln(pixels). */
IVR_API ivr_status ivr_image_entropy(const float* image, const int64_t shape[4], double background,
                                     double* entropy);
/* Peak signal-to-noise ratio with peak 1 of `image` against `reference` (`count` floats each):
 * 10 log10(1 / mse), +infinity when they are equal. */
IVR_API ivr_status ivr_psnr(const float* image, const float* reference, size_t count,
                            double* value);


#ifdef __cplusplus
}
#endif

/* Device-resident sessions and device arrays: in their own header for size. */
#include "ivr/ivr_session.h"
/* Operations shared among workers (MPI ranks, threads): in their own header for size. */
#include "ivr/ivr_split.h"
#endif
