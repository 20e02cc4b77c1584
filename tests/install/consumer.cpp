// consumer.cpp — uses the installed ivr: version macros, the C++ API over the C API (ivr/ivr.hpp)
// and the core C++ API (ivr/core.hpp) in one program, one render through each.
#include <iostream>
#include <ivr/core.hpp>
#include <ivr/ivr.hpp>

int main() {
  ivr::Scene scene;
  scene.volume = ivr::synthetic_volume("sphere", 8, 8, 8);
  ivr::set_default_box(scene);
  ivr::Camera camera;
  camera.width = camera.height = 4;
  scene.cameras = {camera};
  ivr::Device device;
  const ivr::Image image = ivr::render(device, scene);

  ivr::api::Context ctx;
  const ivr::api::Scene api_scene = ctx.scene_from_json(
      R"({"volume": {"synthetic": "sphere", "dims": [8, 8, 8]},
          "cameras": [{"eye": [0, 0, 2], "width": 4, "height": 4}]})");
  const ivr::api::Array<float> api_image = ctx.render(api_scene);

  std::cout << "ivr " << IVR_VERSION_STRING << " rendered " << image.width << "x" << image.height
            << " (core) and " << api_image.shape[2] << "x" << api_image.shape[1] << " (api)\n";
  return image.pixels.size() == 4 * 4 * 4 && api_image.size() == 4 * 4 * 4 &&
                 ivr::api::version() == IVR_VERSION
             ? 0
             : 1;
}
