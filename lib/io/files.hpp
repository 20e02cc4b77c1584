// files.hpp — small file helpers: whole-file reads with clear errors, and atomic writes.
#pragma once
#include <functional>
#include <cstdint>
#include <string>
#include <vector>

namespace ivr {

// Whole file as bytes/text; throws ivr::Error(io) "cannot read <what> 'path': <reason>".
std::vector<unsigned char> read_binary_file(const std::string& path, const std::string& what);
// Bytes [offset, offset + count) of a file; throws Error(io) where it is shorter.
std::vector<unsigned char> read_binary_range(const std::string& path, const std::string& what,
                                             std::uint64_t offset, std::size_t count);
std::string read_text_file(const std::string& path, const std::string& what);

// Calls write(tmp) with a temporary path in the same folder that keeps `path`'s extension, then
// renames it over `path`; on any failure removes the temporary file and rethrows, so a reader
// never sees a half-written file.
void write_atomically(const std::string& path,
                      const std::function<void(const std::string&)>& write);

// Folder part of a path ("." when there is none).
std::string parent_dir(const std::string& path);

}  // namespace ivr
