// consumer.cpp — uses the installed ivr: version macros, a synthetic scene, one render.
#include <iostream>
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
  std::cout << "ivr " << IVR_VERSION_STRING << " rendered " << image.width << "x" << image.height
            << "\n";
  return image.pixels.size() == 4 * 4 * 4 ? 0 : 1;
}
