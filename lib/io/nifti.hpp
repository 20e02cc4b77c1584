// nifti.hpp — internal: the NIfTI-1 reader (.nii, .nii.gz, .hdr/.img pairs).
#pragma once
#include <string>

#include "io/npy.hpp"

namespace ivr::volfile {

// Reads a NIfTI-1 volume: single file (magic "n+1", data at vox_offset) or a .hdr whose data lies
// in the .img (or .img.gz) beside it (magic "ni1"); gzip is detected by its magic bytes; either
// byte order. dim[0] must be 3, or more with size-1 axes beyond the third. Integer and float
// datatypes of 8 to 64 bits (not 64-bit integers, complex or RGB). Spacing is |pixdim[1..3]| (0
// reads as 1). A scl_slope other than 0 or (1, 0) is applied and the values returned as float.
// Throws Error(io) for malformed, truncated or unsupported files and Error(invalid_argument) for
// volumes that are not 3-D.
TypedArray read_nifti(const std::string& path);

}  // namespace ivr::volfile
