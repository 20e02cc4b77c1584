/* render.c — the smallest C program: a volume made in memory rendered through ivr's C API, then
 * d mse / d (TF, background) against a darker copy of the image. Runs with no arguments; exits 0
 * on success and prints one line per step. */
#include <ivr/ivr.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

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
    " \"cameras\": [{\"eye\": [1.2, 0.8, 1.5], \"target\": [0, 0, 0], \"up\": [0, 1, 0],"
    "   \"fov_y\": 40, \"width\": 64, \"height\": 64}]}";

int main(void) {
  enum { N = 32 };
  static float volume[N * N * N]; /* a soft ball in memory: 1 at the centre, 0 at the faces */
  for (int z = 0; z < N; ++z)
    for (int y = 0; y < N; ++y)
      for (int x = 0; x < N; ++x) {
        const double cx = 2.0 * x / (N - 1) - 1, cy = 2.0 * y / (N - 1) - 1,
                     cz = 2.0 * z / (N - 1) - 1;
        const double r = sqrt(cx * cx + cy * cy + cz * cz);
        volume[(z * N + y) * N + x] = (float)(r < 1 ? 1 - r : 0);
      }
  const int64_t volume_shape[3] = {N, N, N};
  ivr_context* ctx = NULL;
  ivr_scene* scene = NULL;
  ivr_result* result = NULL;
  int64_t shape[4];
  /* README: C begin */
  CHECK(ivr_context_create(NULL, &ctx)); /* NULL: $IVR_DEVICE, else a GPU, else the first */
  CHECK(ivr_scene_from_json(ctx, scene_json, NULL, &scene)); /* docs/design.md's JSON */
  CHECK(ivr_scene_set_volume(scene, volume, IVR_FLOAT32, volume_shape)); /* (nz, ny, nx) */
  CHECK(ivr_scene_image_shape(scene, shape)); /* (views, H, W, C) */
  const size_t count = (size_t)(shape[0] * shape[1] * shape[2] * shape[3]);
  float* image = malloc(count * sizeof(float));
  float* target = malloc(count * sizeof(float));
  if (!image || !target) return 1;
  CHECK(ivr_render(ctx, scene, IVR_PRECISION_F32, 0, image, count));
  for (size_t i = 0; i < count; ++i) target[i] = image[i] * 0.9f;
  CHECK(ivr_gradient(ctx, scene, target, count, "tf,background", IVR_MODE_AUTO, IVR_LOSS_MSE,
                     IVR_PRECISION_F32, 0, &result)); /* then ivr_result_info, _array_* */
  /* README: C end */
  double mean = 0;
  for (size_t i = 0; i < count; ++i) mean += image[i];
  printf("rendered %lld x %lld x %lld x %lld, mean %.4f\n", (long long)shape[0],
         (long long)shape[1], (long long)shape[2], (long long)shape[3], mean / (double)count);
  double loss = 0;
  ivr_mode mode = IVR_MODE_AUTO;
  size_t arrays = 0;
  CHECK(ivr_result_info(result, &loss, &mode, NULL));
  CHECK(ivr_result_array_count(result, &arrays));
  printf("loss %.3g, %s mode, %zu gradient arrays\n", loss,
         mode == IVR_MODE_FORWARD ? "forward" : "adjoint", arrays);
  for (size_t a = 0; a < arrays; ++a) {
    const char* name = NULL;
    int rank = 0;
    int64_t dims[5];
    double values[64];
    CHECK(ivr_result_array_shape(result, a, &name, &rank, dims));
    CHECK(ivr_result_array_data(result, a, values, 64));
    printf("  %s: rank %d, first value %.3g\n", name, rank, values[0]);
  }
  free(image);
  free(target);
  CHECK(ivr_result_release(result));
  CHECK(ivr_scene_release(scene));
  CHECK(ivr_context_release(ctx));
  return 0;
}
