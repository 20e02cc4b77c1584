// reconstruct_support.hpp — scenes shared by the reconstruction tests: a 32³ Shepp–Logan
// phantom under an emission–absorption TF, seen by 16 training views on two orbits and 4
// held-out views on a third.
#pragma once
#include <string>

#include "test_support.hpp"

namespace ivr::test {

// The phantom's TF: extinction and colour rising with density, so every density is visible.
inline const char* kPhantomTf =
    R"({"type": "piecewise_linear", "points": [
         {"density": 0, "color": [0, 0, 0], "extinction": 0},
         {"density": 1, "color": [1, 0.7, 0.4], "extinction": 8},
         {"density": 2, "color": [0.5, 0.8, 1], "extinction": 16}]})";

// `cameras`: a JSON array of camera objects or orbits; image size `size`².
inline Scene phantom_scene(const std::string& cameras, int n = 32) {
  const std::string text = R"({"volume": {"synthetic": "zeros", "dims": [)" + std::to_string(n) +
                           "," + std::to_string(n) + "," + std::to_string(n) +
                           R"(]}, "model": "emission_absorption", "tf": )" + kPhantomTf +
                           R"(, "background": [0, 0, 0], "cameras": )" + cameras +
                           R"(, "integrator": {"scheme": "midpoint", "step": 0.5}})";
  Scene s = parse_scene(text, ".", "test scene");
  s.volume = phantom("shepp-logan", n, 1, 2);
  return s;
}

inline std::string orbit(int views, const char* axis, double start, int size) {
  return R"({"orbit": {"views": )" + std::to_string(views) + R"(, "axis": )" + axis +
         R"(, "start": )" + std::to_string(start) + R"(, "radius": 2.2, "fov_y": 40, "width": )" +
         std::to_string(size) + R"(, "height": )" + std::to_string(size) + "}}";
}

// 16 training views of size² (8 about z, 8 about x) and 4 held-out views about y.
inline std::string training_cameras(int size = 64) {
  return "[" + orbit(8, "[0, 0, 1]", 0, size) + ", " + orbit(8, "[1, 0, 0]", 22.5, size) + "]";
}
inline std::string held_out_cameras(int size = 64) {
  return "[" + orbit(4, "[0, 1, 0]", 10, size) + "]";
}

}  // namespace ivr::test
