/* ivr/ivr_session.h — the C API's device-resident sessions, device arrays and density optimisers
 * (included by ivr/ivr.h; the conventions of ownership, errors and threads are ivr.h's). */
#ifndef IVR_IVR_SESSION_H
#define IVR_IVR_SESSION_H
#include "ivr/ivr.h"

#ifdef __cplusplus
extern "C" {
#endif

/* --- Device-resident sessions and device arrays (c_api_session.cpp) --------------------------
 * A session keeps one scene on the device — densities, transfer function, cameras, target and the
 * empty-space grid — so that a loop pays for kernels, not for uploads: each setter uploads only its
 * part (a volume is checked once, on the device); operations enqueue their kernels and return
 * device arrays, read back only by ivr_array_download. A setter or operation that fails leaves the
 * session exactly as it was. Sessions and arrays hold their context; a session may be used by one
 * thread at a time (calls from several are serialised), and sessions of one context may be used
 * from different threads at once. */
typedef struct ivr_session ivr_session; /* a scene resident on a context's device */
typedef struct ivr_array ivr_array;     /* an array in device memory: shape, dtype, buffer */
typedef struct ivr_density_optimizer ivr_density_optimizer; /* Adam/SGD state for densities */

/* A zero-filled array of `rank` (1..8) dimensions `shape` and dtype IVR_FLOAT32 or IVR_FLOAT64. */
IVR_API ivr_status ivr_array_create(ivr_context* context, int rank, const int64_t* shape,
                                    ivr_dtype dtype, ivr_array** array);
IVR_API ivr_status ivr_array_retain(ivr_array* array);
IVR_API ivr_status ivr_array_release(ivr_array* array);
/* Its rank (may be NULL), shape (up to 8 values; may be NULL) and dtype (may be NULL). */
IVR_API ivr_status ivr_array_info(const ivr_array* array, int* rank, int64_t shape[8],
                                  ivr_dtype* dtype);
/* The group an array of ivr_session_gradient holds ("density", "tf", "voxels", …; "" for other
 * arrays): a library-owned string, valid while the array lives. */
IVR_API ivr_status ivr_array_name(const ivr_array* array, const char** name);
/* Host -> device: exactly the array's element count of float32 or float64 values, converted. */
IVR_API ivr_status ivr_array_upload(ivr_array* array, const void* values, ivr_dtype dtype,
                                    size_t count);
/* Device -> host: waits for what writes it, then copies every element as float32 or float64
 * into `values` (`capacity` elements). */
IVR_API ivr_status ivr_array_download(const ivr_array* array, void* values, ivr_dtype dtype,
                                      size_t capacity);
/* Waits until the commands that write the array have finished. */
IVR_API ivr_status ivr_array_wait(const ivr_array* array);
/* An array over the caller's memory `data` (rank, shape and dtype as ivr_array_create). Where the
 * device's memory is the host's (ivr_devices_json's "host_unified_memory": CPUs through PoCL)
 * kernels use that memory itself, no copy: the caller keeps it alive, and does not touch it while
 * an operation that uses the array runs, until the array is released (the release waits for
 * them). Elsewhere the values are copied in once. *borrowed (may be NULL): 1 for the former. */
IVR_API ivr_status ivr_array_wrap(ivr_context* context, void* data, int rank,
                                  const int64_t* shape, ivr_dtype dtype, int* borrowed,
                                  ivr_array** array);
/* The array's values in host memory, in its own dtype: waits for what writes it and maps it — no
 * copy where the device's memory is the host's, one elsewhere (written back at unmap). *data is
 * valid until the last ivr_array_unmap (every map needs one; maps nest) or the array's release.
 * A mapped array must not be written (ivr_array_upload refuses; operations would race). */
IVR_API ivr_status ivr_array_map(const ivr_array* array, void** data);
IVR_API ivr_status ivr_array_unmap(const ivr_array* array);

/* What stays fixed for a session's life. Fill it with ivr_session_options_init. */
typedef struct ivr_session_options {
  size_t size;             /* sizeof the struct, set by the init function (it may grow) */
  ivr_precision precision;   /* IVR_PRECISION_F32: of the device copies and kernels */
  double step;               /* 0; > 0 overrides the scene's integrator step and tolerance */
  int empty_space;           /* 0: automatic, 1: on, 2: off */
  double min_empty_fraction; /* 0.05: automatic skipping needs this fraction of empty bricks */
  int brick_size;            /* 0: automatic (4 up to 128 voxels across, else 8), else 1..64 */
} ivr_session_options;
IVR_API ivr_status ivr_session_options_init(ivr_session_options* options);

/* A session on the scene's context from the scene (copied; its volume is uploaded and checked on
 * the device). options: NULL for the defaults. A scene made from JSON without "volume" gives a
 * session without densities (volume shape (0, 0, 0)) until ivr_session_set_volume. */
IVR_API ivr_status ivr_session_create(ivr_context* context, const ivr_scene* scene,
                                      const ivr_session_options* options, ivr_session** session);
IVR_API ivr_status ivr_session_retain(ivr_session* session);
IVR_API ivr_status ivr_session_release(ivr_session* session);

/* Setters. Densities from host memory: shape (nz, ny, nx) of any size, float32/float64 as they
 * are, uint8/uint16 mapped to [0, 1]; checked (finite, >= 0). Where the scene's JSON gave no box
 * the default box follows the new grid (as for ivr_scene_set_volume), else the box is kept. */
IVR_API ivr_status ivr_session_set_volume(ivr_session* session, const void* data, ivr_dtype dtype,
                                          const int64_t shape[3]);
/* Densities from a device array of shape (nz, ny, nx), copied on the device and checked. */
IVR_API ivr_status ivr_session_set_volume_array(ivr_session* session, const ivr_array* densities);
IVR_API ivr_status ivr_session_set_tf(ivr_session* session, const ivr_transfer_function* tf);
/* The cameras (a scene's "cameras" JSON array: cameras and orbits); their number and image size
 * may change (a target of the old shape is then dropped). */
IVR_API ivr_status ivr_session_set_cameras_json(ivr_session* session, const char* json);
IVR_API ivr_status ivr_session_set_cameras(ivr_session* session, const ivr_camera* cameras,
                                           size_t count);
/* A ray list instead of cameras (as ivr_scene_set_rays: 8 or 6 columns); images and targets are
 * then shaped (rays, channels). ivr_session_set_cameras* go back to cameras. */
IVR_API ivr_status ivr_session_set_rays(ivr_session* session, const double* values, size_t rows,
                                        int columns);
/* A scene's "integrator" JSON object ({"scheme", "step", "min_transmittance", "tolerance"}). */
IVR_API ivr_status ivr_session_set_integrator_json(ivr_session* session, const char* json);
/* RGB (emission-absorption), or background[0] = I_in (absorption). */
IVR_API ivr_status ivr_session_set_background(ivr_session* session, const double background[3]);
/* The loss target: float32 in the image shape, `count` floats, finite. */
IVR_API ivr_status ivr_session_set_target(ivr_session* session, const float* target, size_t count);
IVR_API ivr_status ivr_session_set_target_array(ivr_session* session, const ivr_array* target);

/* (views, height, width, channels) and (nz, ny, nx). */
IVR_API ivr_status ivr_session_image_shape(const ivr_session* session, int64_t shape[4]);
IVR_API ivr_status ivr_session_volume_shape(const ivr_session* session, int64_t shape[3]);
/* A view of the session's densities (its precision): optimiser steps show through it. */
IVR_API ivr_status ivr_session_volume(ivr_session* session, ivr_array** densities);

/* Operations: enqueued on the device; each result is a new array reference for the caller. */
/* Every view: (views, H, W, C), float32, or float64 in a session of precision f64. */
IVR_API ivr_status ivr_session_render(ivr_session* session, ivr_array** image);
/* The loss of the render against `target` (NULL: the session's, checked once when set; a target
 * given here is checked on every call) and its gradient by group, `wrt` as for ivr_gradient:
 * *loss gets shape (1); groups[i] the i-th group's array (at most `capacity`; *count gets how
 * many; ivr_array_name tells each one's group). *ran (may be NULL) gets the mode that ran.
 * deterministic: non-zero sums the adjoint's density gradient in fixed point, the same bits for
 * the same inputs on every run. */
IVR_API ivr_status ivr_session_gradient(ivr_session* session, const ivr_array* target,
                                        const char* wrt, ivr_mode mode, ivr_loss loss,
                                        int deterministic, ivr_array** loss_value,
                                        ivr_array** groups, size_t capacity, size_t* count,
                                        ivr_mode* ran);
/* d pixel / d parameter (forward mode): (views, H, W, C, P), float32, or float64 at f64. */
IVR_API ivr_status ivr_session_jacobian(ivr_session* session, const char* wrt,
                                        ivr_array** jacobian);
/* Line integrals N v of the densities (volume NULL) or of `volume` (nz, ny, nx):
 * (views, H, W, 1) in the session's precision. */
IVR_API ivr_status ivr_session_project(ivr_session* session, const ivr_array* volume,
                                       ivr_array** lines);
/* N^T p of `lines` (views, H, W, 1): (nz, ny, nx). */
IVR_API ivr_status ivr_session_backproject(ivr_session* session, const ivr_array* lines,
                                           ivr_array** volume);
/* The loss (shape (1)) of `image` against `target` (same element count). */
IVR_API ivr_status ivr_session_loss(ivr_session* session, const ivr_array* image,
                                    const ivr_array* target, ivr_loss loss, ivr_array** value);

/* An optimiser for a session's densities (Adam or SGD with momentum, lr > 0; densities kept
 * >= 0), sized and typed for the session as it is now. */
IVR_API ivr_status ivr_density_optimizer_create(ivr_session* session, ivr_optimizer kind,
                                                double lr, ivr_density_optimizer** optimizer);
IVR_API ivr_status ivr_density_optimizer_retain(ivr_density_optimizer* optimizer);
IVR_API ivr_status ivr_density_optimizer_release(ivr_density_optimizer* optimizer);
/* One step on the session's densities in place with the density gradient `gradient`. */
IVR_API ivr_status ivr_session_step(ivr_session* session, ivr_density_optimizer* optimizer,
                                    const ivr_array* gradient);

/* The last operation, once finished (this waits for it). */
typedef struct ivr_operation_stats {
  double kernel_seconds;  /* device time of its kernels (profiling events) */
  double build_seconds;   /* finding or compiling programs (0 once the session has them) */
  uint64_t samples;       /* density samples over all rays (render, gradient, Jacobian) */
  uint64_t device_bytes;  /* device memory of its buffers and the scene's */
  double step;            /* the integrator step used (voxel units) */
  int skipped_empty;      /* empty-space skipping ran */
  double empty_fraction;  /* of the bricks, when the grid was built */
} ivr_operation_stats;
IVR_API ivr_status ivr_session_last_stats(ivr_session* session, ivr_operation_stats* stats);
/* Waits for every command enqueued so far. */
IVR_API ivr_status ivr_session_finish(ivr_session* session);

#ifdef __cplusplus
}
#endif
#endif
