// render.cpp — the C++ API (ivr/ivr.hpp, RAII over the C API): a volume made in memory is
// rendered, then d mse / d (density, TF) against a darker copy of the image. No arguments.
#include <cmath>
#include <iostream>
#include <ivr/ivr.hpp>
#include <vector>

static const char* scene_json = R"({
  "model": "emission_absorption",
  "tf": {"type": "piecewise_linear", "points": [
    {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
    {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
  "cameras": [{"eye": [1.2, 0.8, 1.5], "target": [0, 0, 0], "up": [0, 1, 0],
               "fov_y": 40, "width": 48, "height": 48}]})";

int main() try {
  const int n = 24;  // a soft ball, 1 at the centre, 0 at the faces
  std::vector<float> volume(size_t(n) * n * n);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        auto c = [&](int i) { return 2.0 * i / (n - 1) - 1.0; };
        const double r = std::sqrt(c(x) * c(x) + c(y) * c(y) + c(z) * c(z));
        volume[(size_t(z) * n + y) * n + x] = float(std::fmax(0.0, 1.0 - r));
      }

  // README: C++ begin
  ivr::api::Context ctx;  // $IVR_DEVICE, else a GPU, else the first
  ivr::api::Scene scene = ctx.scene_from_json(scene_json);  // docs/design.md's JSON
  scene.set_volume(volume, {n, n, n});                      // (nz, ny, nx), copied
  ivr::api::Array<float> image = ctx.render(scene);         // shape (views, H, W, C)

  std::vector<float> target = image.values;
  for (float& v : target) v *= 0.9f;
  ivr::api::GradientOptions options;  // f32, mse, auto mode
  options.wrt = "density,tf";
  ivr::api::Result g = ctx.gradient(scene, target, options);
  ivr::api::Array<double> d_density = g.array("density");  // (nz, ny, nx)
  // README: C++ end

  std::cout << "rendered on " << ctx.device_name() << ": " << image.shape[1] << "x"
            << image.shape[2] << "x" << image.shape[3] << "\n"
            << "loss " << g.loss() << " in "
            << (g.mode() == ivr::api::Mode::forward ? "forward" : "adjoint") << " mode\n";
  double norm = 0;
  for (double v : d_density.values) norm += v * v;
  for (const ivr::api::NamedArray& a : g.arrays())
    std::cout << "  d loss / d " << a.name << ": " << a.array.size() << " values\n";
  // The target is darker than the render, so the gradient is not zero.
  return norm > 0 && std::isfinite(norm) && g.loss() > 0 ? 0 : 1;
} catch (const ivr::api::Exception& e) {
  std::cerr << "error (" << ivr_status_string(e.status()) << "): " << e.what() << "\n";
  return 1;
}
