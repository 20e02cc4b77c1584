// volume_io.cpp — load_volume: format dispatch, raw and .cvol reading, mapping to float densities.
#include "ivr/volume_io.hpp"

#include <cctype>
#include <climits>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>

#include "io/files.hpp"
#include "ivr/error.hpp"
#include "io/nifti.hpp"
#include "io/npy.hpp"
#include "io/nrrd.hpp"

namespace ivr {

namespace {

using volfile::ScalarType;
using volfile::TypedArray;

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string num(double v) {
  std::ostringstream out;
  out.precision(9);
  out << v;
  return out.str();
}

std::string dims_text(long long x, long long y, long long z) {
  return std::to_string(x) + "x" + std::to_string(y) + "x" + std::to_string(z);
}

// "npy", "nrrd", "nifti", "raw" or "cvol", from `format` when given, else from the extension.
std::string format_of(const VolumeSource& s) {
  std::string f = lower(s.format);
  if (!f.empty() && f[0] == '.') f.erase(0, 1);
  if (!f.empty()) {
    if (f == "npy" || f == "nrrd" || f == "nifti" || f == "raw" || f == "cvol") return f;
    if (f == "nhdr") return "nrrd";
    if (f == "nii" || f == "nii.gz") return "nifti";
    throw Error(Status::invalid_argument, "unknown volume format '" + s.format +
                                              "' (use npy, nrrd, nhdr, nifti, raw or cvol): '" +
                                              s.path + "'");
  }
  const std::filesystem::path p(s.path);
  const std::string ext = lower(p.extension().string());
  // .nii.gz and .hdr.gz: the extension before ".gz" decides (gzip is detected by its magic).
  const std::string inner = ext == ".gz" ? lower(p.stem().extension().string()) : ext;
  if (ext == ".npy") return "npy";
  if (ext == ".nrrd" || ext == ".nhdr") return "nrrd";
  if (inner == ".nii" || inner == ".hdr") return "nifti";
  if (ext == ".raw") return "raw";
  if (ext == ".cvol") return "cvol";
  throw Error(Status::invalid_argument, "cannot tell the volume format from the extension '" + ext +
                                            "' (use .npy, .nrrd, .nhdr, .nii, .nii.gz, .hdr, .raw "
                                            "or .cvol, or give a format): '" +
                                            s.path + "'");
}

TypedArray read_raw(const VolumeSource& s) {
  if (!s.dims)
    throw Error(Status::invalid_argument, "raw volume needs dims (X, Y, Z): '" + s.path + "'");
  if (s.type.empty())
    throw Error(Status::invalid_argument, "raw volume needs a type: '" + s.path + "'");
  const std::optional<ScalarType> type = volfile::parse_scalar_type(s.type);
  if (!type)
    throw Error(Status::invalid_argument,
                "unknown raw volume type '" + s.type +
                    "' (use uint8, int8, uint16, int16, uint32, int32, float32 or float64): '" +
                    s.path + "'");
  const std::string endian = lower(s.endian);
  if (!endian.empty() && endian != "little" && endian != "big")
    throw Error(Status::invalid_argument, "raw volume endian must be 'little' or 'big', not '" +
                                              s.endian + "': '" + s.path + "'");
  const glm::ivec3 d = *s.dims;
  const std::string dims = dims_text(d.x, d.y, d.z);
  if (d.x < 1 || d.y < 1 || d.z < 1)
    throw Error(Status::invalid_argument,
                "raw volume dims must all be >= 1, got " + dims + ": '" + s.path + "'");
  TypedArray a;
  a.type = *type;
  a.big_endian = endian == "big";
  a.shape = {std::size_t(d.z), std::size_t(d.y), std::size_t(d.x)};
  const std::size_t need =
      volfile::checked_count(a.shape, volfile::kMaxVoxels, s.path) * volfile::scalar_size(a.type);
  auto mismatch = [&](std::size_t have) {
    return Error(Status::invalid_argument, "raw volume '" + s.path + "' has " +
                                               std::to_string(have) + " bytes but dims " + dims +
                                               " of " + volfile::scalar_name(a.type) + " need " +
                                               std::to_string(need));
  };
  // Check the size before reading, so wrong dims on a huge file fail fast.
  std::error_code ec;
  const auto size = std::filesystem::file_size(s.path, ec);
  if (!ec && size != need) throw mismatch(std::size_t(size));
  if (s.planes && !ec) {  // only the chosen planes' bytes
    const auto [first, last] = s.planes(d.z);
    if (first < 0 || last < first || last >= d.z)
      throw Error(Status::invalid_argument, "raw volume '" + s.path + "': planes " +
                                                std::to_string(first) + ".." + std::to_string(last) +
                                                " of " + std::to_string(d.z));
    const std::size_t plane = std::size_t(d.x) * d.y * volfile::scalar_size(a.type);
    a.bytes = read_binary_range(s.path, "raw volume", std::uint64_t(first) * plane,
                                std::size_t(last - first + 1) * plane);
    a.first_plane = std::size_t(first);
    a.planes = last - first + 1;
    return a;
  }
  a.bytes = read_binary_file(s.path, "raw volume");
  if (a.bytes.size() != need) throw mismatch(a.bytes.size());
  return a;
}

// DiffDVR's .cvol: 64-byte little-endian header, then the voxels, x fastest.
TypedArray read_cvol(const std::string& path) {
  TypedArray a;
  a.bytes = read_binary_file(path, ".cvol file");
  const std::vector<unsigned char>& b = a.bytes;
  auto fail = [&](const std::string& what) { return Error(Status::io, what + ": '" + path + "'"); };
  constexpr std::size_t kHeader = 64;
  if (b.size() < 4 || std::memcmp(b.data(), "cvol", 4) != 0)
    throw fail("not a .cvol file (bad magic, expected 'cvol')");
  if (b.size() < kHeader)
    throw fail("truncated .cvol header (" + std::to_string(b.size()) + " bytes, needs 64)");
  std::uint64_t dims[3];
  double voxel[3];
  for (int i = 0; i < 3; ++i) {
    dims[i] = volfile::load_scalar<std::uint64_t>(&b[4 + 8 * i], volfile::host_is_big_endian());
    voxel[i] = volfile::load_scalar<double>(&b[28 + 8 * i], volfile::host_is_big_endian());
  }
  const std::int32_t code =
      volfile::load_scalar<std::int32_t>(&b[52], volfile::host_is_big_endian());
  if (b[56] != 0) throw fail("compressed .cvol (LZ4) is not supported; save it uncompressed");
  if (code == 0) {
    a.type = ScalarType::uint8;
  } else if (code == 1) {
    a.type = ScalarType::uint16;
  } else if (code == 2) {
    a.type = ScalarType::float32;
  } else {
    throw fail("unsupported .cvol data type " + std::to_string(code) +
               " (0 = uint8, 1 = uint16, 2 = float32 are)");
  }
  for (int i = 0; i < 3; ++i) {
    if (dims[i] < 1 || dims[i] > volfile::kMaxVoxels)
      throw Error(Status::invalid_argument,
                  ".cvol dims " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                      std::to_string(dims[2]) + " must each be in [1, 2^31]: '" + path + "'");
    if (!(std::isfinite(voxel[i]) && voxel[i] > 0))
      throw fail("malformed .cvol voxel size (" + num(voxel[0]) + ", " + num(voxel[1]) + ", " +
                 num(voxel[2]) + ")");
  }
  a.shape = {std::size_t(dims[2]), std::size_t(dims[1]), std::size_t(dims[0])};
  const std::size_t need =
      volfile::checked_count(a.shape, volfile::kMaxVoxels, path) * volfile::scalar_size(a.type);
  if (b.size() - kHeader != need)
    throw fail(std::string(b.size() - kHeader < need ? "truncated" : "trailing bytes in") +
               " .cvol (data has " + std::to_string(b.size() - kHeader) + " bytes but dims " +
               std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
               std::to_string(dims[2]) + " of " + volfile::scalar_name(a.type) + " need " +
               std::to_string(need) + ")");
  a.offset = kHeader;
  a.spacing = glm::dvec3(voxel[0], voxel[1], voxel[2]);
  return a;
}

// Integer-type range mapped to [0, 1] by default.
void type_range(ScalarType type, double* lo, double* hi) {
  switch (type) {
    case ScalarType::uint8:
      *lo = 0, *hi = 255;
      return;
    case ScalarType::int8:
      *lo = -128, *hi = 127;
      return;
    case ScalarType::uint16:
      *lo = 0, *hi = 65535;
      return;
    case ScalarType::int16:
      *lo = -32768, *hi = 32767;
      return;
    case ScalarType::uint32:
      *lo = 0, *hi = 4294967295.0;
      return;
    case ScalarType::int32:
      *lo = -2147483648.0, *hi = 2147483647.0;
      return;
    case ScalarType::float32:
    case ScalarType::float64:
      *lo = 0, *hi = 1;
      return;
  }
}

// Range and spacing overrides are checked before any file is read.
void check_overrides(const VolumeSource& s) {
  if (s.range &&
      !(std::isfinite(s.range->x) && std::isfinite(s.range->y) && s.range->y > s.range->x))
    throw Error(Status::invalid_argument, "volume range [" + num(s.range->x) + ", " +
                                              num(s.range->y) + "] needs finite lo < hi: '" +
                                              s.path + "'");
  if (s.spacing) {
    const glm::dvec3 sp = *s.spacing;
    for (int i = 0; i < 3; ++i)
      if (!(std::isfinite(sp[i]) && sp[i] > 0))
        throw Error(Status::invalid_argument,
                    "volume spacing (" + num(sp.x) + ", " + num(sp.y) + ", " + num(sp.z) +
                        ") must be positive and finite: '" + s.path + "'");
  }
}

Volume to_volume(const TypedArray& a, const VolumeSource& s) {
  const std::string& path = s.path;
  if (a.shape.size() != 3) {
    std::string shape;
    for (std::size_t n : a.shape) shape += (shape.empty() ? "" : ", ") + std::to_string(n);
    throw Error(Status::invalid_argument,
                "volume must be 3-D (Z, Y, X) but has shape (" + shape + "): '" + path + "'");
  }
  for (std::size_t n : a.shape)
    if (n < 1 || n > std::size_t(INT_MAX))
      throw Error(Status::invalid_argument,
                  "volume dims " + dims_text(a.shape[2], a.shape[1], a.shape[0]) +
                      " (X x Y x Z) must each be >= 1 and < 2^31: '" + path + "'");
  volfile::checked_count(a.shape, volfile::kMaxVoxels, path);
  // (Only some planes read: the values are theirs, the dims the whole volume's.)
  const std::size_t planes = a.planes < 0 ? a.shape[0] : std::size_t(a.planes);
  const std::size_t count = planes * a.shape[1] * a.shape[2];

  double lo = 0, hi = 1;
  type_range(a.type, &lo, &hi);
  if (s.range) {
    lo = s.range->x;
    hi = s.range->y;
  }
  const bool identity = lo == 0 && hi == 1;

  Volume v;
  v.nx = int(a.shape[2]);
  v.ny = int(a.shape[1]);
  v.nz = int(a.shape[0]);
  v.data.resize(count);
  std::size_t bad = count;  // index of the first voxel that is not a finite, non-negative float
  double bad_value = 0, bad_density = 0;
  float* out = v.data.data();
  volfile::for_each_value(a, count, [&](std::size_t i, double value) {
    const double d = identity ? value : (value - lo) / (hi - lo);
    const float f = static_cast<float>(d);
    out[i] = f;
    if (!(f >= 0.0f && std::isfinite(f)) && bad == count) {
      bad = i;
      bad_value = value;
      bad_density = d;
    }
  });
  if (bad != count) {
    const std::size_t x = bad % a.shape[2], y = bad / a.shape[2] % a.shape[1],
                      z = a.first_plane + bad / (a.shape[2] * a.shape[1]);
    std::string what;
    if (std::isnan(bad_density)) {
      what = "NaN density";
    } else if (std::isinf(bad_density)) {
      what = "infinite density " + num(bad_density);
    } else if (bad_density < 0) {
      what = "negative density " + num(bad_density);
    } else {
      what = "density " + num(bad_density) + " too large for float32";
    }
    if (!identity && !std::isnan(bad_density))
      what += " (value " + num(bad_value) + " mapped by range [" + num(lo) + ", " + num(hi) + "])";
    throw Error(Status::invalid_argument, what + " at voxel (x, y, z) = (" + std::to_string(x) +
                                              ", " + std::to_string(y) + ", " + std::to_string(z) +
                                              ") in volume '" + path + "'");
  }

  v.spacing = s.spacing.value_or(a.spacing.value_or(glm::dvec3(1.0)));
  return v;
}

// Keeps only the planes source.planes chooses of a whole 3-D array (formats read whole).
void keep_planes(TypedArray& a, const VolumeSource& s) {
  if (!s.planes || a.planes >= 0 || a.shape.size() != 3 || a.shape[0] > std::size_t(INT_MAX)) return;
  const auto [first, last] = s.planes(int(a.shape[0]));
  if (first < 0 || last < first || std::size_t(last) >= a.shape[0])
    throw Error(Status::invalid_argument, "volume '" + s.path + "': planes " +
                                              std::to_string(first) + ".." + std::to_string(last) +
                                              " of " + std::to_string(a.shape[0]));
  const std::size_t plane = a.shape[1] * a.shape[2] * volfile::scalar_size(a.type);
  const auto begin = a.bytes.begin() + std::ptrdiff_t(a.offset + std::size_t(first) * plane);
  a.bytes = std::vector<unsigned char>(begin, begin + std::ptrdiff_t(std::size_t(last - first + 1) * plane));
  a.offset = 0;
  a.first_plane = std::size_t(first);
  a.planes = last - first + 1;
}

}  // namespace

Volume load_volume(const VolumeSource& source) {
  const std::string format = format_of(source);
  check_overrides(source);
  TypedArray a;
  if (format == "npy") {
    a = volfile::read_npy(source.path, source.planes);
  } else if (format == "nrrd") {
    a = volfile::read_nrrd(source.path);
  } else if (format == "nifti") {
    a = volfile::read_nifti(source.path);
  } else if (format == "raw") {
    a = read_raw(source);
  } else {
    a = read_cvol(source.path);
  }
  keep_planes(a, source);
  return to_volume(a, source);
}

}  // namespace ivr
