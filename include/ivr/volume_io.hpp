// ivr/volume_io.hpp — reading volumes (.npy, NRRD, NIfTI-1, raw, DiffDVR .cvol), writing .npy.
#pragma once
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "ivr/export.h"
#include "ivr/scene.hpp"

namespace ivr {

// How to read a volume file. For raw files dims and type are required; for the other formats
// they come from the file's header. Integer data maps to [0, 1] by its type's range unless
// `range` is given (then d = (v - lo) / (hi - lo)). `spacing` overrides the file's spacing.
// NIfTI data with a scl_slope (other than 0 or 1 with scl_inter 0) is scaled to float as it is
// read, so it is used as is, or mapped by `range`.
struct VolumeSource {
  std::string path;
  std::string format;  // "" = from the extension: .npy, .nrrd/.nhdr, .nii(.gz)/.hdr, .raw, .cvol
  std::optional<glm::ivec3> dims;  // raw: (X, Y, Z)
  std::string type;  // raw: uint8, int8, uint16, int16, uint32, int32, float32, float64
  std::string endian = "little";  // raw: little or big
  std::optional<glm::dvec2> range;
  std::optional<glm::dvec3> spacing;
  // Only planes [first, last] of z, chosen from the volume's nz (a domain worker's slab:
  // domain_slab, docs/scaling.md): the Volume keeps the whole dims and `data` holds those planes
  // (x fastest). .npy (C order) and raw files read only the header and those planes' bytes; the
  // other formats read the whole file and keep the planes.
  std::function<std::pair<int, int>(int nz)> planes;
};

// Reads and maps a volume; throws ivr::Error(io) for missing/unreadable/malformed files and
// ivr::Error(invalid_argument) for sizes that do not match, NaN/Inf or negative densities.
IVR_API Volume load_volume(const VolumeSource& source);

// Writes a float32 (float64) .npy of the given shape (C order), through a temporary file and a
// rename.
IVR_API void save_npy(const std::string& path, const std::vector<std::size_t>& shape,
                      const float* data);
IVR_API void save_npy(const std::string& path, const std::vector<std::size_t>& shape,
                      const double* data);

// Writes the volume as NRRD (float, raw, little-endian, with its spacing), atomically.
IVR_API void save_nrrd(const std::string& path, const Volume& volume);

// A .npy read back as float64 with its shape and stored type (tests, tools); throws
// ivr::Error(io).
struct NpyArray {
  std::vector<std::size_t> shape;
  std::vector<double> data;
  std::string dtype;  // the stored type: "float32", "float64", "uint16", …
};
IVR_API NpyArray load_npy(const std::string& path);

}  // namespace ivr
