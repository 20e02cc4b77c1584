// fuzz_cvol.cpp — DiffDVR .cvol bytes through load_volume.
#include "fuzz_support.hpp"
#include "ivr/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ivr::fuzz::put("in.cvol", data, size);
  ivr::fuzz::clean([&] { ivr::load_volume({path}); });
  return 0;
}
