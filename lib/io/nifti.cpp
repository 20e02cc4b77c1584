// nifti.cpp — NIfTI-1 volumes: header parsing, byte order, gzip, .hdr/.img pairs, scl_slope.
#include "io/nifti.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "io/files.hpp"
#include "io/gzip.hpp"
#include "ivr/error.hpp"

// What is used from the 348-byte header: sizeof_hdr, dim, datatype, pixdim[1..3], vox_offset,
// scl_slope, scl_inter, magic. Ignored:
// - the orientation (qform/sform, quatern_*, srow_*): voxel (i, j, k) is placed at ivr's (x, y, z)
//   in index order, so data stored with flipped or permuted world axes renders flipped or rotated
//   relative to a viewer that applies the orientation;
// - xyzt_units (only the ratios of the spacings matter to ivr's box), bitpix (the datatype
//   decides), intent, cal_min/cal_max, slice timing, and header extensions (skipped by
//   vox_offset).
// Data order: NIfTI stores x fastest like ivr, so the data is used without transposition.
//
// Mapping to densities: without a scaling the stored type is kept, so integer data maps to [0, 1]
// by its type's range (or the scene's `range`) as in every other format, and float data is used
// as is. With a scaling (scl_slope nonzero and not (1, 0)) the stored values are converted here to
// d = slope * v + inter as float, so, like float data in other formats, they are densities as they
// stand: a scaled volume with values outside [0, 1] needs the scene's `range` (negative densities
// are rejected).

namespace ivr::volfile {

namespace {

constexpr std::size_t kHeaderSize = 348;
constexpr const char* kKind = "NIfTI";

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw Error(Status::io, what + ": '" + path + "'");
}

std::string num(double v) {
  std::string s = std::to_string(v);
  s.erase(s.find_last_not_of('0') + 1);
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// The NIfTI-1 datatype code as a scalar type; throws for the codes ivr does not read.
ScalarType datatype(int code, const std::string& path) {
  switch (code) {
    case 2:
      return ScalarType::uint8;
    case 4:
      return ScalarType::int16;
    case 8:
      return ScalarType::int32;
    case 16:
      return ScalarType::float32;
    case 64:
      return ScalarType::float64;
    case 256:
      return ScalarType::int8;
    case 512:
      return ScalarType::uint16;
    case 768:
      return ScalarType::uint32;
    default:
      break;
  }
  const char* name = nullptr;
  switch (code) {
    case 1:
      name = "binary";
      break;
    case 32:
      name = "complex64";
      break;
    case 128:
      name = "rgb24";
      break;
    case 1024:
      name = "int64";
      break;
    case 1280:
      name = "uint64";
      break;
    case 1536:
      name = "float128";
      break;
    case 1792:
      name = "complex128";
      break;
    case 2048:
      name = "complex256";
      break;
    case 2304:
      name = "rgba32";
      break;
  }
  const std::string what =
      name ? "unsupported NIfTI datatype " + std::to_string(code) + " (" + name + ")"
           : "unknown NIfTI datatype " + std::to_string(code);
  fail(path, what + "; supported: uint8, int8, uint16, int16, uint32, int32, float32, float64");
}

// The file's bytes, inflated to `want` bytes when it is gzip (the whole file otherwise).
std::vector<unsigned char> data_bytes(std::vector<unsigned char> file, std::size_t want,
                                      const std::string& path) {
  if (!is_gzip(file.data(), file.size())) return file;
  return gunzip(file.data(), file.size(), want, path, kKind);
}

// The .img (or .img.gz) beside a .hdr (or .hdr.gz), keeping the extension's case.
std::string image_path(const std::string& header) {
  std::filesystem::path p(header);
  std::string gz;
  if (p.extension() == ".gz" || p.extension() == ".GZ") {
    gz = p.extension().string();
    p.replace_extension();
  }
  const bool upper = p.extension() == ".HDR";
  p.replace_extension(upper ? ".IMG" : ".img");
  const std::string plain = p.string(), zipped = plain + (upper ? ".GZ" : ".gz");
  std::error_code ec;
  if (!gz.empty() && std::filesystem::exists(zipped, ec)) return zipped;
  if (std::filesystem::exists(plain, ec) || !std::filesystem::exists(zipped, ec)) return plain;
  return zipped;
}

}  // namespace

TypedArray read_nifti(const std::string& path) {
  std::vector<unsigned char> file = read_binary_file(path, "NIfTI file");
  const bool gz = is_gzip(file.data(), file.size());
  const std::vector<unsigned char> head =
      gz ? gunzip_head(file.data(), file.size(), kHeaderSize, path, kKind)
         : std::vector<unsigned char>(
               file.begin(), file.begin() + std::ptrdiff_t(std::min(file.size(), kHeaderSize)));
  if (head.size() < 4)
    fail(path,
         "not a NIfTI-1 file (" + std::to_string(head.size()) + " bytes, too short for a header)");

  // Byte order: sizeof_hdr is 348 read in the file's order.
  const bool host_big = host_is_big_endian();
  TypedArray a;
  const std::int32_t size_le = load_scalar<std::int32_t>(head.data(), host_big);
  const std::int32_t size_be = load_scalar<std::int32_t>(head.data(), !host_big);
  if (size_le == 348) {
    a.big_endian = false;
  } else if (size_be == 348) {
    a.big_endian = true;
  } else if (size_le == 540 || size_be == 540) {
    fail(path, "NIfTI-2 files are not supported (sizeof_hdr 540); save it as NIfTI-1");
  } else {
    fail(path, "not a NIfTI-1 file (sizeof_hdr is " + std::to_string(size_le) + ", expected 348)");
  }
  if (head.size() < kHeaderSize)
    fail(path, "truncated NIfTI header (" + std::to_string(head.size()) + " of 348 bytes)");
  const bool swap = a.big_endian != host_big;
  auto i16 = [&](std::size_t at) { return load_scalar<std::int16_t>(&head[at], swap); };
  auto f32 = [&](std::size_t at) { return double(load_scalar<float>(&head[at], swap)); };

  const bool single = std::memcmp(&head[344], "n+1\0", 4) == 0;
  if (!single && std::memcmp(&head[344], "ni1\0", 4) != 0)
    fail(path,
         "not a NIfTI-1 file (bad magic, expected 'n+1' or 'ni1'; plain ANALYZE 7.5 headers are "
         "not supported)");

  // dim[0] axes of sizes dim[1..]; ivr reads x, y, z and lets further axes of size 1 go.
  const int rank = i16(40);
  if (rank < 1 || rank > 7) fail(path, "malformed NIfTI dim[0] = " + std::to_string(rank));
  std::size_t dim[8] = {};
  std::string sizes;
  for (int i = 1; i <= rank; ++i) {
    const int n = i16(40 + 2 * std::size_t(i));
    if (n < 1) fail(path, "malformed NIfTI dim[" + std::to_string(i) + "] = " + std::to_string(n));
    dim[i] = std::size_t(n);
    sizes += (i > 1 ? "x" : "") + std::to_string(n);
  }
  bool extra = false;
  for (int i = 4; i <= rank; ++i) extra = extra || dim[i] != 1;
  if (rank < 3 || extra)
    throw Error(Status::invalid_argument,
                "NIfTI volume must be 3-D (dim[0] = 3, or more with axes beyond the third of "
                "size 1) but has dim[0] = " +
                    std::to_string(rank) + " and sizes " + sizes + ": '" + path + "'");
  a.shape = {dim[3], dim[2], dim[1]};
  a.type = datatype(i16(70), path);

  glm::dvec3 spacing;
  for (int i = 0; i < 3; ++i) {
    const double p = f32(80 + 4 * std::size_t(i));
    if (!std::isfinite(p)) fail(path, "malformed NIfTI pixdim[" + std::to_string(i + 1) + "]");
    spacing[i] = p == 0 ? 1.0 : std::fabs(p);  // the sign only states a direction
  }
  a.spacing = spacing;

  const double vox_offset = f32(108);
  const double min_offset = single ? double(kHeaderSize) : 0.0;
  if (!(std::isfinite(vox_offset) && vox_offset >= min_offset && vox_offset < 1e15 &&
        vox_offset == std::floor(vox_offset)))
    fail(path, "malformed NIfTI vox_offset " + num(vox_offset) +
                   (single ? " (a .nii needs a whole number >= 348)" : ""));
  const std::size_t offset = std::size_t(vox_offset);
  const std::size_t count = checked_count(a.shape, kMaxVoxels, path);
  const std::size_t need = count * scalar_size(a.type);

  // The data: this file after vox_offset, or the .img beside a "ni1" header.
  std::string data_path = path;
  if (!single) {
    data_path = image_path(path);
    file = read_binary_file(data_path, "NIfTI image file (for header '" + path + "')");
  }
  a.bytes = data_bytes(std::move(file), offset + need, data_path);
  if (a.bytes.size() < offset + need)
    fail(data_path, "truncated NIfTI data (" +
                        std::to_string(a.bytes.size() - std::min(a.bytes.size(), offset)) +
                        " bytes after vox_offset " + std::to_string(offset) + " but dims " + sizes +
                        " of " + scalar_name(a.type) + " need " + std::to_string(need) + ")");
  a.offset = offset;

  // scl_slope / scl_inter (a NaN or infinite slope means none, as nibabel reads it).
  const double slope = f32(112), inter_raw = f32(116);
  const double inter = std::isfinite(inter_raw) ? inter_raw : 0.0;
  if (std::isfinite(slope) && slope != 0 && !(slope == 1 && inter == 0)) {
    // float32 keeps slope * v + inter of 8- and 16-bit data and float32 data as well as ivr's
    // float32 densities can; wider types go through float64.
    const bool wide = a.type == ScalarType::int32 || a.type == ScalarType::uint32 ||
                      a.type == ScalarType::float64;
    std::vector<unsigned char> scaled(count * (wide ? 8 : 4));
    unsigned char* out = scaled.data();
    for_each_value(a, count, [&](std::size_t i, double v) {
      const double d = slope * v + inter;
      if (wide) {
        std::memcpy(out + 8 * i, &d, 8);
      } else {
        const float f = static_cast<float>(d);
        std::memcpy(out + 4 * i, &f, 4);
      }
    });
    a.bytes = std::move(scaled);
    a.offset = 0;
    a.type = wide ? ScalarType::float64 : ScalarType::float32;
    a.big_endian = host_big;
  }
  return a;
}

}  // namespace ivr::volfile
