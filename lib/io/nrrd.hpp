// nrrd.hpp — internal: the NRRD reader (.nrrd with attached data, .nhdr with a detached data file).
#pragma once
#include <string>

#include "io/npy.hpp"

namespace ivr::volfile {

// Reads a 3-D NRRD (a 4-D one whose first axis has size 1 reads as 3-D) with raw, gzip or ascii
// encoding; spacing comes from "spacings" or the norms of "space directions". Throws Error(io) for
// malformed or unsupported files and Error(invalid_argument) for unusable sizes.
TypedArray read_nrrd(const std::string& path);

}  // namespace ivr::volfile
