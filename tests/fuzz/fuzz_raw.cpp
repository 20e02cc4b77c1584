// fuzz_raw.cpp — a raw volume and its description: bytes 0–5 are dims X, Y, Z (uint16 each, so
// they may claim far more than the file holds), byte 6 the type, byte 7 the byte order and
// whether bytes 8–23 give a value range (two doubles); the rest is the file.
#include <cstring>

#include "fuzz_support.hpp"
#include "ivr/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 24) return 0;
  static const char* const types[9] = {"uint8",   "int8",    "uint16", "int16", "uint32",
                                       "int32",   "float32", "float64", "complex"};
  ivr::VolumeSource s;
  auto u16 = [&](int i) { return int(data[i]) | int(data[i + 1]) << 8; };
  s.dims = glm::ivec3(u16(0), u16(2), u16(4));
  s.type = types[data[6] % 9];
  s.endian = data[7] & 1 ? "big" : "little";
  if (data[7] & 2) {
    double range[2];
    std::memcpy(range, data + 8, sizeof range);
    s.range = glm::dvec2(range[0], range[1]);
  }
  s.path = ivr::fuzz::put("in.raw", data + 24, size - 24);
  ivr::fuzz::clean([&] { ivr::load_volume(s); });
  return 0;
}
