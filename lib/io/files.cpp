// files.cpp — whole-file reads with clear errors and write-to-temporary-then-rename.
#include "io/files.hpp"

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <thread>

#include "ivr/error.hpp"

namespace fs = std::filesystem;

namespace ivr {

namespace {
void check_readable(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw Error(Status::io, "cannot read " + what + " '" + path + "': no such file");
  if (fs::is_directory(path, ec))
    throw Error(Status::io, "cannot read " + what + " '" + path + "': it is a directory");
}
}  // namespace

std::vector<unsigned char> read_binary_file(const std::string& path, const std::string& what) {
  check_readable(path, what);
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw Error(Status::io, "cannot read " + what + " '" + path + "': " + std::strerror(errno));
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  if (in.bad()) throw Error(Status::io, "cannot read " + what + " '" + path + "': read error");
  return bytes;
}

std::vector<unsigned char> read_binary_range(const std::string& path, const std::string& what,
                                             std::uint64_t offset, std::size_t count) {
  check_readable(path, what);
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw Error(Status::io, "cannot read " + what + " '" + path + "': " + std::strerror(errno));
  std::vector<unsigned char> bytes(count);
  in.seekg(std::streamoff(offset));
  in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(count));
  if (std::size_t(in.gcount()) != count)
    throw Error(Status::io, "cannot read " + what + " '" + path + "': " + std::to_string(count) +
                                " bytes at offset " + std::to_string(offset) + " are past its end");
  return bytes;
}

std::string read_text_file(const std::string& path, const std::string& what) {
  const std::vector<unsigned char> bytes = read_binary_file(path, what);
  return std::string(bytes.begin(), bytes.end());
}

namespace {

// $IVR_TEST_PAUSE_BEFORE_RENAME=TEXT[:N] (tests only): the Nth write (default 1st) of a path
// containing TEXT stops with its temporary file complete and not yet renamed, says so on stderr,
// and waits to be killed — so a test can SIGKILL a process in the middle of a write for real.
void pause_for_fault_tests(const std::string& tmp, const std::string& path) {
  static const char* spec = std::getenv("IVR_TEST_PAUSE_BEFORE_RENAME");
  if (!spec || !*spec) return;
  static std::atomic<int> seen{0};
  std::string text = spec;
  int nth = 1;
  if (const std::size_t colon = text.rfind(':'); colon != std::string::npos) {
    nth = std::atoi(text.c_str() + colon + 1);
    text.erase(colon);
  }
  if (path.find(text) == std::string::npos || ++seen != nth) return;
  std::fprintf(stderr, "ivr: paused before renaming '%s' to '%s'\n", tmp.c_str(), path.c_str());
  std::fflush(stderr);
  for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
}

}  // namespace

void write_atomically(const std::string& path,
                      const std::function<void(const std::string&)>& write) {
  const fs::path target(path);
  if (target.filename().empty())
    throw Error(Status::io, "cannot write '" + path + "': not a file name");
  std::error_code ec;
  if (fs::is_directory(target, ec))
    throw Error(Status::io, "cannot write '" + path + "': it is a directory");
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec))
    throw Error(Status::io,
                "cannot write '" + path + "': folder '" + dir.string() + "' does not exist");
  std::random_device rd;
  const fs::path tmp = dir / ("." + target.stem().string() + ".tmp" +
                              std::to_string(rd() % 1000000) + target.extension().string());
  try {
    write(tmp.string());
    pause_for_fault_tests(tmp.string(), path);
    fs::rename(tmp, target);
  } catch (const fs::filesystem_error& e) {
    fs::remove(tmp, ec);
    throw Error(Status::io, "cannot write '" + path + "': " + e.code().message());
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
}

std::string parent_dir(const std::string& path) {
  const fs::path p(path);
  return p.has_parent_path() ? p.parent_path().string() : ".";
}

}  // namespace ivr
