/* consumer.c — a C program built against the installed ivr through pkg-config: the C API only. */
#include <ivr/ivr.h>
#include <stdio.h>

int main(void) {
  if (ivr_version() != IVR_VERSION) {
    fprintf(stderr, "header %d, library %d\n", IVR_VERSION, ivr_version());
    return 1;
  }
  size_t needed = 0;
  if (ivr_devices_json(NULL, 0, &needed) != IVR_OK || needed < 2) {
    fprintf(stderr, "ivr_devices_json: %s\n", ivr_last_error());
    return 1;
  }
  ivr_context* ctx = NULL;
  ivr_scene* scene = NULL;
  float image[4 * 4 * 4];
  const char* json =
      "{\"volume\": {\"synthetic\": \"sphere\", \"dims\": [8, 8, 8]},"
      " \"cameras\": [{\"eye\": [0, 0, 2], \"width\": 4, \"height\": 4}]}";
  if (ivr_context_create(NULL, &ctx) != IVR_OK || ivr_scene_from_json(ctx, json, NULL, &scene) ||
      ivr_render(ctx, scene, IVR_PRECISION_F32, 0, image, 64) != IVR_OK) {
    fprintf(stderr, "%s\n", ivr_last_error());
    return 1;
  }
  printf("C consumer rendered, centre alpha %.3f\n", image[(2 * 4 + 2) * 4 + 3]);
  ivr_scene_release(scene);
  ivr_context_release(ctx);
  return 0;
}
