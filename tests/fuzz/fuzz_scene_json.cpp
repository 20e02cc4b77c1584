// fuzz_scene_json.cpp — scene JSON text through parse_scene, with a small valid volume file
// (vol.npy) beside it for "file" entries to name.
#include <vector>

#include "fuzz_support.hpp"
#include "ivr/scene.hpp"
#include "ivr/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool volume_written = [] {
    std::vector<float> v(4 * 4 * 4);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(i % 7) / 7.f;
    ivr::save_npy(ivr::fuzz::scratch() + "/vol.npy", {4, 4, 4}, v.data());
    return true;
  }();
  (void)volume_written;
  const std::string text(reinterpret_cast<const char*>(data), size);
  if (ivr::fuzz::asks_for_large_synthetic(text)) return 0;
  ivr::fuzz::clean([&] { ivr::parse_scene(text, ivr::fuzz::scratch(), "fuzz scene"); });
  return 0;
}
