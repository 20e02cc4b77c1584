// fuzz_nifti.cpp — NIfTI-1 bytes: the first byte picks .nii, .nii.gz or a .hdr whose .img (the
// same bytes) lies beside it; gzip is recognised by its magic whatever the name.
#include "fuzz_support.hpp"
#include "ivr/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const names[3] = {"in.nii", "in.nii.gz", "in.hdr"};
  const char* name = names[data[0] % 3];
  if (data[0] % 3 == 2) ivr::fuzz::put("in.img", data + 1, size - 1);
  const std::string path = ivr::fuzz::put(name, data + 1, size - 1);
  ivr::fuzz::clean([&] { ivr::load_volume({path}); });
  return 0;
}
