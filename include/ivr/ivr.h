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
 * Threads: a context and everything created from it may be used by one thread at a time;
 * separate contexts may be used concurrently from separate threads. Handle bookkeeping (retain,
 * release, validation) is thread-safe. */
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
  IVR_LOSS_MAX_ENUM = 0x7fffffff
} ivr_loss;

typedef struct ivr_context ivr_context; /* a device, its queue and program cache, a last error */
typedef struct ivr_scene ivr_scene;     /* a scene with its volume (belongs to one context) */
typedef struct ivr_result ivr_result;   /* a gradient or Jacobian: loss, mode, named arrays */
typedef struct ivr_volume ivr_volume;   /* densities (nz, ny, nx) with their voxel spacing */
typedef struct ivr_transfer_function ivr_transfer_function; /* DESIGN.md's "tf" object */

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

/* A scene from DESIGN.md's JSON text; relative volume paths resolve against base_dir (NULL: the
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
/* Volumes and transfer functions of their own, made once and set on any scene of the context
 * (the scene takes a copy: later changes to one do not reach the other). */
/* A volume from caller memory, copied (dtypes as ivr_scene_set_volume), spacing 1. */
IVR_API ivr_status ivr_volume_create(ivr_context* context, const void* data, ivr_dtype dtype,
                                     const int64_t shape[3], ivr_volume** volume);
/* A volume from DESIGN.md's "volume" object, e.g. {"file": "head.nrrd"} or {"synthetic":
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
/* A transfer function from DESIGN.md's "tf" object, checked as in a scene. */
IVR_API ivr_status ivr_tf_from_json(ivr_context* context, const char* json,
                                    ivr_transfer_function** tf);
IVR_API ivr_status ivr_tf_retain(ivr_transfer_function* tf);
IVR_API ivr_status ivr_tf_release(ivr_transfer_function* tf);
/* Copies the transfer function into the scene, replacing its own. */
IVR_API ivr_status ivr_scene_set_tf(ivr_scene* scene, const ivr_transfer_function* tf);

/* The shape of the scene's images: (views, height, width, channels). */
IVR_API ivr_status ivr_scene_image_shape(const ivr_scene* scene, int64_t shape[4]);
/* The volume's shape (nz, ny, nx). */
IVR_API ivr_status ivr_scene_volume_shape(const ivr_scene* scene, int64_t shape[3]);

/* The integrator step (voxel units) a render of the scene uses: the scene's own, or, where its
 * integrator asks for a "tolerance", the step chosen for it (pilot renders at a quarter of the
 * resolution, Richardson: README "Integrators"); *estimated_error (may be NULL) receives that
 * step's estimated relative RMS error (0 without a tolerance). Renders with step 0 use this step.
 */
IVR_API ivr_status ivr_scene_step(ivr_context* context, const ivr_scene* scene,
                                  ivr_precision precision, double* step, double* estimated_error);

/* Renders every view into `image`: float32, shape ivr_scene_image_shape, `capacity` floats. step
 * > 0 overrides the scene's integrator step and tolerance (voxel units). */
IVR_API ivr_status ivr_render(ivr_context* context, const ivr_scene* scene, ivr_precision precision,
                              double step, float* image, size_t capacity);

/* The loss of the render against `target` (float32, the image shape; `count` floats) and its
 * gradient with respect to the comma-separated groups in `wrt` (as `ivr grad --wrt`: density,
 * tf, tf_points, scales, background, camera, step, voxels:LIST), in `mode`. */
IVR_API ivr_status ivr_gradient(ivr_context* context, const ivr_scene* scene, const float* target,
                                size_t count, const char* wrt, ivr_mode mode, ivr_loss loss,
                                ivr_precision precision, double step, ivr_result** result);
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

#ifdef __cplusplus
}
#endif
#endif
