/* render.c — the smallest C program: a built-in Marschner–Lobb volume rendered through ivr's C
 * API, then d mse / d (TF, background) against a shifted copy of the image. Runs with no
 * arguments; exits 0 on success and prints one line per step. */
#include <ivr/ivr.h>
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
    "{\"volume\": {\"synthetic\": \"marschner_lobb\", \"dims\": [32, 32, 32]},"
    " \"model\": \"emission_absorption\","
    " \"tf\": {\"type\": \"piecewise_linear\", \"points\": ["
    "   {\"density\": 0.0, \"color\": [0, 0, 0], \"extinction\": 0},"
    "   {\"density\": 0.6, \"color\": [1, 0.8, 0.6], \"extinction\": 20}]},"
    " \"background\": [0, 0, 0],"
    " \"cameras\": [{\"eye\": [1.2, 0.8, 1.5], \"target\": [0, 0, 0], \"up\": [0, 1, 0],"
    "   \"fov_y\": 40, \"width\": 64, \"height\": 64}]}";

int main(void) {
  ivr_context* ctx = NULL;
  ivr_scene* scene = NULL;
  ivr_result* result = NULL;
  int64_t shape[4];
  CHECK(ivr_context_create(NULL, &ctx));
  CHECK(ivr_scene_from_json(ctx, scene_json, NULL, &scene));
  CHECK(ivr_scene_image_shape(scene, shape));
  const size_t count = (size_t)(shape[0] * shape[1] * shape[2] * shape[3]);
  float* image = malloc(count * sizeof(float));
  float* target = malloc(count * sizeof(float));
  if (!image || !target) return 1;
  CHECK(ivr_render(ctx, scene, IVR_PRECISION_F32, 0, image, count));
  double mean = 0;
  for (size_t i = 0; i < count; ++i) mean += image[i];
  printf("rendered %lld x %lld x %lld x %lld, mean %.4f\n", (long long)shape[0],
         (long long)shape[1], (long long)shape[2], (long long)shape[3], mean / (double)count);

  for (size_t i = 0; i < count; ++i) target[i] = image[i] * 0.9f;
  CHECK(ivr_gradient(ctx, scene, target, count, "tf,background", IVR_MODE_AUTO, IVR_LOSS_MSE,
                     IVR_PRECISION_F32, 0, &result));
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
