// fuzz_npy.cpp — .npy bytes through load_volume (volumes) and load_npy (checkpoints, tools).
#include "fuzz_support.hpp"
#include "ivr/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ivr::fuzz::put("in.npy", data, size);
  ivr::fuzz::clean([&] { ivr::load_volume({path}); });
  ivr::fuzz::clean([&] { ivr::load_npy(path); });
  return 0;
}
