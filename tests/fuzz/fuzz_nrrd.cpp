// fuzz_nrrd.cpp — NRRD bytes: the first byte picks .nrrd (attached data) or .nhdr (detached);
// the rest is the file, and also d.raw and d.raw.gz beside it for a detached header to name.
#include "fuzz_support.hpp"
#include "ivr/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const bool detached = data[0] & 1;
  ivr::fuzz::put("d.raw", data + 1, size - 1);
  ivr::fuzz::put("d.raw.gz", data + 1, size - 1);
  const std::string path = ivr::fuzz::put(detached ? "in.nhdr" : "in.nrrd", data + 1, size - 1);
  ivr::fuzz::clean([&] { ivr::load_volume({path}); });
  return 0;
}
