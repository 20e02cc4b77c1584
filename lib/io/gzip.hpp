// gzip.hpp — internal: gzip inflation shared by the volume readers (NRRD gzip encoding, .nii.gz).
#pragma once
#include <cstddef>
#include <string>
#include <vector>

namespace ivr::volfile {

// True when `data` starts with the gzip magic bytes 1f 8b.
bool is_gzip(const unsigned char* data, std::size_t size);

// Decompresses gzip data (concatenated members too) into exactly `want` bytes. It inflates on to
// the end of the member that completes the data, so the CRC is checked; extra output is discarded.
// The buffer grows as data arrives, so a lying header cannot allocate memory the data does not
// fill. Throws Error(io) "truncated/corrupted gzip data in <kind>: 'path'".
std::vector<unsigned char> gunzip(const unsigned char* data, std::size_t size, std::size_t want,
                                  const std::string& path, const std::string& kind);

// The first `max` bytes of the inflated stream (fewer when it ends sooner), for reading a header
// before the data size is known; stops there, so the CRC is not checked. Throws Error(io) for
// corrupted data.
std::vector<unsigned char> gunzip_head(const unsigned char* data, std::size_t size, std::size_t max,
                                       const std::string& path, const std::string& kind);

}  // namespace ivr::volfile
