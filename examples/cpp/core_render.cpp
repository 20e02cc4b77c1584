// core_render.cpp — the core C++ API (ivr/core.hpp): load a scene, render it, save a PNG.
// Usage: core_render SCENE.json OUT.png
#include <iostream>
#include <ivr/core.hpp>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: core_render SCENE.json OUT.png\n";
    return 2;
  }
  try {
    const ivr::Scene scene = ivr::load_scene(argv[1]);
    ivr::Device device;  // $IVR_DEVICE, else the first GPU, else the first device
    ivr::RenderStats stats;
    const ivr::Image image = ivr::render(device, scene, {}, &stats);
    ivr::save_image_file(argv[2], image, 0);
    std::cout << "rendered on " << device.info().name << " in " << stats.kernel_seconds * 1e3
              << " ms\n";
  } catch (const ivr::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
