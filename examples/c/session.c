/* session.c — a device-resident session through ivr's C API: the scene stays on the device, a loop
 * of gradients and Adam steps recovers a ball's densities from two of its images, and only the
 * loss comes back to the host each iteration. Runs with no arguments; exits 0 on success, else
 * prints the failing call's status and message and exits 1. */
#include <ivr/ivr.h>
#include <math.h>
#include <stdio.h>

#define CHECK(call)                                                              \
  do {                                                                           \
    const ivr_status status_ = (call);                                           \
    if (status_ != IVR_OK) {                                                     \
      fprintf(stderr, "%s: %s\n", ivr_status_string(status_), ivr_last_error()); \
      return 1;                                                                  \
    }                                                                            \
  } while (0)

static const char* scene_json =
    "{\"model\": \"emission_absorption\","
    " \"tf\": {\"type\": \"piecewise_linear\", \"points\": ["
    "   {\"density\": 0.0, \"color\": [0, 0, 0], \"extinction\": 0},"
    "   {\"density\": 0.6, \"color\": [1, 0.8, 0.6], \"extinction\": 20}]},"
    " \"background\": [0, 0, 0],"
    " \"cameras\": [{\"orbit\": {\"views\": 2, \"radius\": 2, \"axis\": [0, 1, 0], \"arc\": 180,"
    "   \"fov_y\": 40, \"width\": 32, \"height\": 32}}]}";

enum { N = 24 };

int main(void) {
  static float truth[N * N * N], start[N * N * N]; /* a soft ball; the start is half as dense */
  for (int z = 0; z < N; ++z)
    for (int y = 0; y < N; ++y)
      for (int x = 0; x < N; ++x) {
        const double cx = 2.0 * x / (N - 1) - 1, cy = 2.0 * y / (N - 1) - 1,
                     cz = 2.0 * z / (N - 1) - 1;
        const double r = sqrt(cx * cx + cy * cy + cz * cz);
        const int i = (z * N + y) * N + x;
        truth[i] = (float)(r < 1 ? 1 - r : 0);
        start[i] = 0.5f * truth[i];
      }
  const int64_t volume_shape[3] = {N, N, N};
  ivr_context* ctx = NULL;
  ivr_scene* scene = NULL;
  ivr_session* session = NULL;
  ivr_array* target = NULL;
  ivr_density_optimizer* adam = NULL;
  int64_t shape[4];

  CHECK(ivr_context_create(NULL, &ctx)); /* NULL: $IVR_DEVICE, else a GPU, else the first */
  const char* device = NULL;
  CHECK(ivr_context_device_name(ctx, &device));
  CHECK(ivr_scene_from_json(ctx, scene_json, NULL, &scene));            /* docs/design.md's JSON */
  CHECK(ivr_scene_set_volume(scene, truth, IVR_FLOAT32, volume_shape)); /* (nz, ny, nx) */
  CHECK(ivr_session_create(ctx, scene, NULL, &session)); /* the scene goes to the device */
  CHECK(ivr_scene_release(scene));                       /* the session has its own copy */

  /* The render of the true densities is the target; it never leaves the device. */
  CHECK(ivr_session_render(session, &target));
  CHECK(ivr_session_set_target_array(session, target));
  CHECK(ivr_session_image_shape(session, shape)); /* (views, H, W, C) */
  printf("%s: rendered %lld x %lld x %lld x %lld\n", device, (long long)shape[0],
         (long long)shape[1], (long long)shape[2], (long long)shape[3]);

  /* Start from half the densities and step towards the target's. */
  CHECK(ivr_session_set_volume(session, start, IVR_FLOAT32, volume_shape));
  CHECK(ivr_density_optimizer_create(session, IVR_OPTIMIZER_ADAM, 0.02, &adam));
  double first = 0, last = 0;
  for (int k = 0; k < 8; ++k) {
    ivr_array* loss = NULL;
    ivr_array* gradient = NULL; /* one group: "density" */
    CHECK(ivr_session_gradient(session, NULL, "density", IVR_MODE_ADJOINT, IVR_LOSS_MSE, 0, &loss,
                               &gradient, 1, NULL, NULL));
    CHECK(ivr_session_step(session, adam, gradient));       /* densities stay >= 0 */
    CHECK(ivr_array_download(loss, &last, IVR_FLOAT64, 1)); /* the one value read back */
    CHECK(ivr_array_release(gradient));
    CHECK(ivr_array_release(loss));
    if (k == 0) first = last;
    printf("iteration %d: loss %.4g\n", k, last);
  }

  /* The stepped densities, read back through a view of the session's own buffer. */
  ivr_array* densities = NULL;
  static float recovered[N * N * N];
  CHECK(ivr_session_volume(session, &densities));
  CHECK(ivr_array_download(densities, recovered, IVR_FLOAT32, N * N * N));
  double error_start = 0, error_now = 0;
  for (int i = 0; i < N * N * N; ++i) {
    error_start += fabs((double)start[i] - truth[i]);
    error_now += fabs((double)recovered[i] - truth[i]);
  }
  printf("mean density error %.4f -> %.4f\n", error_start / (N * N * N), error_now / (N * N * N));

  CHECK(ivr_array_release(densities));
  CHECK(ivr_density_optimizer_release(adam));
  CHECK(ivr_array_release(target));
  CHECK(ivr_session_release(session));
  CHECK(ivr_context_release(ctx));
  if (!(last < first)) {
    fprintf(stderr, "the loss did not go down: %g -> %g\n", first, last);
    return 1;
  }
  return 0;
}
