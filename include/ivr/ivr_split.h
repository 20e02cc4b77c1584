/* ivr/ivr_split.h — the C API's operations shared among workers (MPI ranks, threads): the
 * gradient data-parallel over views, render and gradient over slabs or segments, tomography and
 * reconstruction split over views or slabs (docs/scaling.md). Included by ivr/ivr.h; the
 * conventions of ownership, errors and threads are ivr.h's. */
#ifndef IVR_IVR_SPLIT_H
#define IVR_IVR_SPLIT_H
#include "ivr/ivr.h"

#ifdef __cplusplus
extern "C" {
#endif

/* --- Gradients and renders (c_api.cpp) ------------------------------------------------------ */
/* ivr_gradient as worker `rank` of `ranks` data-parallel over views (docs/scaling.md), every
 * worker calling it together with the whole scene and target: each differentiates its share of
 * the views (a ray list: rays) and the workers' results are combined through `sum` (ivr_sum_fn,
 * below), so every worker gets the whole loss and gradient. `deterministic` non-zero: the density
 * gradient summed in fixed point (adjoint mode, where every worker's device has 64-bit integer
 * atomics and a view): the same bits on every run and, over workers, one process's bits. With
 * ranks 1, `sum` may be NULL (ivr_gradient with `deterministic`). */
typedef int (*ivr_sum_fn)(double* values, size_t count, void* user);
IVR_API ivr_status ivr_gradient_shared(ivr_context* context, const ivr_scene* scene,
                                       const float* target, size_t count, const char* wrt,
                                       ivr_mode mode, ivr_loss loss, ivr_precision precision,
                                       double step, int deterministic, int rank, int ranks,
                                       ivr_sum_fn sum, void* sum_user, ivr_result** result);
/* ivr_gradient_shared with the workers' shares of the views in proportion to `shares` (`ranks`
 * weights, each > 0 and finite, the same on every worker; NULL: equal shares, as
 * ivr_gradient_shared): ivr_view_shares(n, shares, ranks, 0, …)'s counts. A worker whose share is
 * empty adds zeros (and the density gradient is then not summed in fixed point). */
IVR_API ivr_status ivr_gradient_shared_weighted(ivr_context* context, const ivr_scene* scene,
                                                const float* target, size_t count,
                                                const char* wrt, ivr_mode mode, ivr_loss loss,
                                                ivr_precision precision, double step,
                                                int deterministic, int rank, int ranks,
                                                const double* shares, ivr_sum_fn sum,
                                                void* sum_user, ivr_result** result);
/* Contiguous shares of n views (or rays) over `parts` workers in proportion to `weights` (`parts`
 * of them, each > 0 and finite; NULL: equal): counts[i] (parts of them) the ith worker's views,
 * share i holding about n·wᵢ/Σw, the remainders to the largest fractions (ties to the lower
 * index). `each` non-zero: every worker at least one view where n >= parts (where the weighted
 * split leaves one empty: one view each, the rest by the weights; n < parts: one each to the
 * first n) — what `mpirun ivr` gives the ranks. The split depends on the weights alone. */
IVR_API ivr_status ivr_view_shares(size_t n, const double* weights, size_t parts, int each,
                                   size_t* counts);
/* The context's device's render speed, samples per second, from its cost model (`ivr
 * calibrate`'s file where there is one, else estimated from the device's size): the default
 * weight of its share of the views (docs/scaling.md). */
IVR_API ivr_status ivr_context_samples_per_second(const ivr_context* context, double* speed);
/* How a split operation shares the work among its workers. */
typedef enum ivr_split {
  IVR_SPLIT_VIEWS = 0, /* each worker its share of the views (or rays) and the whole volume */
  IVR_SPLIT_SLABS = 1, /* each worker one slab of z planes of the volume and every view, the
                          rays' march states passed from slab to slab */
  IVR_SPLIT_SEGMENTS = 2, /* each worker one slab and every view, each ray's segments marched
                             independently and composited in order (render, gradient,
                             reconstruction: docs/scaling.md) */
  IVR_SPLIT_MAX_ENUM = 0x7fffffff
} ivr_split;

/* ivr_render and ivr_gradient as worker `rank` of `ranks` over slabs (docs/scaling.md), every
 * worker calling it together: each marches only planes ivr_domain_slab(nz, rank, ranks) of the
 * scene's volume on its device (the scene holds the whole volume; the slab is cut from it), the
 * rays' march states passed between the workers through `sum` (ivr_sum_fn). The image is the
 * whole render on every worker. The gradient (every scheme) holds this worker's parts:
 * "density" its planes (planes, ny, nx) — add the workers' where neighbours share a plane — and
 * "tf" the part
 * from its samples (sum it over the workers); "background" and the forward lanes' groups (camera,
 * scales, tf_points, voxels:LIST) are whole on every worker, as is the loss.
 * ivr_sum_fn: a sum over the workers of a split operation, called by every worker together:
 * `values` (`count` doubles) replaced by their elementwise sum over the workers, the same on every
 * worker — an MPI_Allreduce with MPI_SUM from the caller's MPI. Return non-zero on success.
 * ivr_render_split and ivr_gradient_split: the same with the slab march `split` names —
 * IVR_SPLIT_SLABS (the march states passed, as ivr_render_slabs) or IVR_SPLIT_SEGMENTS (every
 * worker marches its slab's segment of every ray at once, from transmittance 1; one exchange of
 * the segments, composited in order per ray — the forward lanes' tangents with them —; the
 * adjoint seeded from the composited front). Over segments early termination stops a segment
 * only where its own transmittance falls below the threshold (docs/scaling.md). */
IVR_API ivr_status ivr_render_slabs(ivr_context* context, const ivr_scene* scene,
                                    ivr_precision precision, double step, int rank, int ranks,
                                    ivr_sum_fn sum, void* sum_user, float* image, size_t capacity);
IVR_API ivr_status ivr_gradient_slabs(ivr_context* context, const ivr_scene* scene,
                                      const float* target, size_t count, const char* wrt,
                                      ivr_loss loss, ivr_precision precision, double step, int rank,
                                      int ranks, ivr_sum_fn sum, void* sum_user,
                                      ivr_result** result);
IVR_API ivr_status ivr_render_split(ivr_context* context, const ivr_scene* scene,
                                    ivr_precision precision, double step, ivr_split split,
                                    int rank, int ranks, ivr_sum_fn sum, void* sum_user,
                                    float* image, size_t capacity);
IVR_API ivr_status ivr_gradient_split(ivr_context* context, const ivr_scene* scene,
                                      const float* target, size_t count, const char* wrt,
                                      ivr_loss loss, ivr_precision precision, double step,
                                      ivr_split split, int rank, int ranks, ivr_sum_fn sum,
                                      void* sum_user, ivr_result** result);
/* ivr_render_split and ivr_gradient_split with each worker's slab in proportion to its weight
 * (`shares`: `ranks` weights, each > 0 and finite, the same on every worker — a device's speed,
 * ivr_context_samples_per_second —; NULL or all equal: the equal slabs): worker `rank` marches
 * planes ivr_domain_slab_weighted(nz, rank, ranks, shares), so that a fast device's longer slab
 * takes about as long as a slow one's short slab. A scene holding one slab
 * (ivr_scene_set_volume_slab_weighted) must have been given the same shares. */
IVR_API ivr_status ivr_render_split_weighted(ivr_context* context, const ivr_scene* scene,
                                             ivr_precision precision, double step,
                                             ivr_split split, int rank, int ranks,
                                             const double* shares, ivr_sum_fn sum,
                                             void* sum_user, float* image, size_t capacity);
IVR_API ivr_status ivr_gradient_split_weighted(ivr_context* context, const ivr_scene* scene,
                                               const float* target, size_t count,
                                               const char* wrt, ivr_loss loss,
                                               ivr_precision precision, double step,
                                               ivr_split split, int rank, int ranks,
                                               const double* shares, ivr_sum_fn sum,
                                               void* sum_user, ivr_result** result);
/* ivr_gradient_split_weighted with the density gradient summed in fixed point where
 * `deterministic` is non-zero (every worker passing the same flag) and every worker's device has
 * 64-bit integer atomics: the same bits on every run and, over IVR_SPLIT_SLABS, one process's
 * in-core gradient bit for bit once the workers' "density" parts are added — a plane two workers
 * share is whole on the upper one, 0 on the lower (every scheme; docs/scaling.md). Where a worker's device lacks 64-bit integer atomics every worker
 * sums in float instead, and a shared plane's parts lie on both. */
IVR_API ivr_status ivr_gradient_split_deterministic(ivr_context* context, const ivr_scene* scene,
                                                    const float* target, size_t count,
                                                    const char* wrt, ivr_loss loss,
                                                    ivr_precision precision, double step,
                                                    ivr_split split, int deterministic, int rank,
                                                    int ranks, const double* shares, ivr_sum_fn sum,
                                                    void* sum_user, ivr_result** result);

/* --- Tomography (c_api_tomo.cpp) ------------------------------------------------------------ */

/* ivr_tomo as worker `rank` of `ranks` (CGLS, SIRT or LSQR, with nonneg, tikhonov or tv; over
 * slabs each worker holds the TV rows of its own planes), every worker calling it
 * together with the same options; `sum` (with `sum_user`) adds over the workers.
 * IVR_SPLIT_VIEWS: `scene` holds this worker's share of the views (or rays) and `lines` (`count`
 * floats) their projections; `volume` receives the whole grid (nz * ny * nx), the same on every
 * worker. IVR_SPLIT_SLABS: `scene` and `lines` are the whole scene's, on every worker; `volume`
 * receives this worker's planes [first, last] of the grid (planes * ny * nx floats; the slab of
 * ivr_domain_slab), the planes neighbours share alike on both. progress, history and summary as
 * ivr_tomo's. Equal to one process's ivr_tomo to rounding. (No IVR_SPLIT_SEGMENTS: a line
 * integral's slab parts add in one sum already.) */
IVR_API ivr_status ivr_tomo_split(ivr_context* context, const ivr_scene* scene,
                                  const ivr_tomo_options* options, ivr_split split, int rank,
                                  int ranks, ivr_sum_fn sum, void* sum_user, const float* lines,
                                  size_t count, float* volume, size_t capacity,
                                  ivr_tomo_progress progress, void* user,
                                  ivr_tomo_iteration* history, size_t history_capacity,
                                  ivr_tomo_summary* summary);
/* ivr_tomo_split with, over slabs, each worker's planes ivr_domain_slab_weighted(nz, rank, ranks,
 * shares) (`shares` as ivr_render_split_weighted's; NULL: equal slabs). Over views each worker
 * passes its own views, so `shares` must be NULL there (ivr_view_shares cuts them). */
IVR_API ivr_status ivr_tomo_split_weighted(ivr_context* context, const ivr_scene* scene,
                                           const ivr_tomo_options* options, ivr_split split,
                                           int rank, int ranks, const double* shares,
                                           ivr_sum_fn sum, void* sum_user, const float* lines,
                                           size_t count, float* volume, size_t capacity,
                                           ivr_tomo_progress progress, void* user,
                                           ivr_tomo_iteration* history, size_t history_capacity,
                                           ivr_tomo_summary* summary);
/* Worker `rank` of `ranks`' planes [*first, *last] of a volume of nz planes: its nz - 1 cells in
 * near-equal runs, neighbours sharing one plane (IVR_ERROR_INVALID_ARGUMENT where ranks > nz - 1). */
IVR_API ivr_status ivr_domain_slab(int nz, int rank, int ranks, int* first, int* last);
/* The same with the cells in proportion to `shares` (`ranks` weights, each > 0 and finite; NULL or
 * all equal: ivr_domain_slab's runs): the largest-remainder split, every worker at least one
 * cell. What the _weighted split operations march and ivr_scene_set_volume_slab_weighted takes. */
IVR_API ivr_status ivr_domain_slab_weighted(int nz, int rank, int ranks, const double* shares,
                                            int* first, int* last);

/* --- Reconstruction (c_api_reconstruct.cpp) ------------------------------------------------- */
/* ivr_reconstruction_create for worker `worker` of `workers` sharing out each batch's views
 * (docs/scaling.md; every worker passes the whole scene and targets and the same options): every
 * step's loss and gradients are summed over the workers through `sum` (ivr_sum_fn: an
 * MPI_Allreduce from the caller; kept and called by every step, so it and `sum_user` must outlive
 * the handle), so that every worker takes the same step and holds the same iterate. Cameras only;
 * every batch needs at least `workers` views. */
IVR_API ivr_status ivr_reconstruction_create_shared(ivr_context* context, const ivr_scene* scene,
                                                    const float* targets, size_t count,
                                                    const ivr_reconstruct_options* options,
                                                    int worker, int workers, ivr_sum_fn sum,
                                                    void* sum_user,
                                                    ivr_reconstruction** reconstruction);
/* ivr_reconstruction_create_shared with the work shared as `split` says (every worker creating its
 * reconstruction together: over slabs with an identity TF the creation sums over the workers):
 * IVR_SPLIT_VIEWS is
 * ivr_reconstruction_create_shared; IVR_SPLIT_SLABS (mpirun ivr reconstruct --split slabs): every
 * worker passes the whole scene (its volume: the start with init scene) and targets, holds only
 * planes ivr_domain_slab(nz, worker, workers) of the densities and their optimiser state, and
 * marches every view of each batch through them, the rays' states passed through `sum`
 * (IVR_SPLIT_SEGMENTS: each ray's segments marched at once and composited in order); the
 * densities (and the TF jointly), cameras only. ivr_reconstruction_volume then returns this
 * worker's planes of the current level's grid (planes * ny * nx; those neighbours share alike on
 * both), and
 * ivr_reconstruction_result_scene is refused (it would hold one slab). */
IVR_API ivr_status ivr_reconstruction_create_split(ivr_context* context, const ivr_scene* scene,
                                                   const float* targets, size_t count,
                                                   const ivr_reconstruct_options* options,
                                                   ivr_split split, int worker, int workers,
                                                   ivr_sum_fn sum, void* sum_user,
                                                   ivr_reconstruction** reconstruction);
/* ivr_reconstruction_create_split with, over views, each batch's shares in proportion to `shares`
 * (`workers` weights, each > 0 and finite, the same on every worker; NULL: equal shares); every
 * worker's share of a batch must hold a view (pass ivr_view_shares(batch, …, each = 1)'s counts
 * as the weights: they split the batch into exactly those counts). Over slabs and segments the
 * worker holds planes ivr_domain_slab_weighted(nz, worker, workers, shares) of every level's
 * grid (NULL: equal slabs). */
IVR_API ivr_status ivr_reconstruction_create_weighted(ivr_context* context,
                                                      const ivr_scene* scene,
                                                      const float* targets, size_t count,
                                                      const ivr_reconstruct_options* options,
                                                      ivr_split split, int worker, int workers,
                                                      const double* shares, ivr_sum_fn sum,
                                                      void* sum_user,
                                                      ivr_reconstruction** reconstruction);

#ifdef __cplusplus
}
#endif

#endif
