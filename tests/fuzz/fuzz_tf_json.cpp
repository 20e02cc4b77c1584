// fuzz_tf_json.cpp — the JSON of a scene's parts on their own: transfer function, cameras,
// integrator and inline volume, each parsed from the same text.
#include "fuzz_support.hpp"
#include "ivr/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  if (ivr::fuzz::asks_for_large_synthetic(text)) return 0;
  ivr::fuzz::clean([&] { ivr::parse_tf(text, "fuzz tf"); });
  ivr::fuzz::clean([&] { ivr::parse_cameras(text, "fuzz cameras"); });
  ivr::fuzz::clean([&] { ivr::parse_integrator(text, "fuzz integrator"); });
  ivr::fuzz::clean([&] { ivr::parse_volume(text, ivr::fuzz::scratch(), "fuzz volume"); });
  return 0;
}
