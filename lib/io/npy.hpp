// npy.hpp — internal: element types shared by the volume readers, typed arrays, and the .npy
// reader.
#pragma once
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <glm/vec3.hpp>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace ivr::volfile {

enum class ScalarType { uint8, int8, uint16, int16, uint32, int32, float32, float64 };

std::size_t scalar_size(ScalarType type);
const char* scalar_name(ScalarType type);  // "uint8", "int16", "float32", ...
bool is_integer(ScalarType type);
// Canonical names plus the usual C / NRRD spellings ("uchar", "unsigned short", "int16_t",
// "float", "double", ...); nullopt for anything else.
std::optional<ScalarType> parse_scalar_type(const std::string& name);

bool host_is_big_endian();

// Product of `shape`; throws Error(invalid_argument) naming `path` when it exceeds `limit` (checked
// before each multiplication, so it never overflows).
std::size_t checked_count(const std::vector<std::size_t>& shape, std::size_t limit,
                          const std::string& path);

// Most voxels a volume may have.
constexpr std::size_t kMaxVoxels = std::size_t(1) << 31;

// An array as stored in a file: count() elements of `type`, C order, starting at bytes[offset].
struct TypedArray {
  std::vector<std::size_t> shape;  // slowest axis first: (Z, Y, X) for volumes
  ScalarType type = ScalarType::float32;
  bool big_endian = false;
  std::vector<unsigned char> bytes;
  std::size_t offset = 0;
  // Where only some planes (along the slowest axis) were read: the first, and how many bytes holds
  // (-1: all of shape[0]).
  std::size_t first_plane = 0;
  long long planes = -1;
  std::optional<glm::dvec3> spacing;  // (x, y, z) voxel size when the file states one
};

// Chooses the planes [first, last] to read from the count along the slowest axis.
using PlaneChooser = std::function<std::pair<int, int>(int count)>;

// Reads a .npy of a supported dtype (f4, f8, u1, i1, u2, i2, u4, i4, either byte order) and any
// number of dimensions; Fortran-order data is transposed to C order. Throws Error(io). With
// `planes` (3-D, C order): only the header and the chosen planes' bytes are read (first_plane,
// planes set); otherwise the whole file.
TypedArray read_npy(const std::string& path, const PlaneChooser& planes = {});

template <class T>
T load_scalar(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  T value;
  std::memcpy(&value, b, sizeof(T));
  return value;
}

// Calls f(i, value) with every element as a double, in storage order, fixing the byte order.
template <class F>
void for_each_value(const TypedArray& a, std::size_t count, F&& f) {
  const bool swap = a.big_endian != host_is_big_endian();
  const unsigned char* p = a.bytes.data() + a.offset;
  auto run = [&](auto zero) {
    using T = decltype(zero);
    for (std::size_t i = 0; i < count; ++i)
      f(i, static_cast<double>(load_scalar<T>(p + i * sizeof(T), swap)));
  };
  switch (a.type) {
    case ScalarType::uint8:
      return run(std::uint8_t{});
    case ScalarType::int8:
      return run(std::int8_t{});
    case ScalarType::uint16:
      return run(std::uint16_t{});
    case ScalarType::int16:
      return run(std::int16_t{});
    case ScalarType::uint32:
      return run(std::uint32_t{});
    case ScalarType::int32:
      return run(std::int32_t{});
    case ScalarType::float32:
      return run(float{});
    case ScalarType::float64:
      return run(double{});
  }
}

}  // namespace ivr::volfile
