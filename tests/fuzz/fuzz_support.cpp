// fuzz_support.cpp — the fuzz harnesses' scratch folder and file writer.
#include "fuzz_support.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace fs = std::filesystem;

namespace ivr::fuzz {

namespace {

// The folder, removed with its files when the process exits normally.
struct Scratch {
  std::string path;
  Scratch() {
    const char* tmp = std::getenv("TMPDIR");
    path = (fs::path(tmp && *tmp ? tmp : "/tmp") / ("ivr-fuzz-" + std::to_string(::getpid())))
               .string();
    fs::create_directories(path);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

}  // namespace

const std::string& scratch() {
  static const Scratch dir;
  return dir.path;
}

std::string put(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const std::string path = scratch() + "/" + name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  if (!out) throw std::runtime_error("fuzz harness: cannot write " + path);
  return path;
}

std::string put(const std::string& name, const std::string& text) {
  return put(name, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

namespace {

bool large_synthetic(const nlohmann::json& j) {
  if (j.is_object() && j.contains("synthetic") && j.contains("dims") && j["dims"].is_array()) {
    double voxels = 1;
    for (const auto& d : j["dims"]) voxels *= d.is_number() ? std::abs(d.get<double>()) : 1.0;
    if (voxels > double(1 << 21)) return true;
  }
  if (j.is_structured())
    for (const auto& child : j)
      if (large_synthetic(child)) return true;
  return false;
}

}  // namespace

bool asks_for_large_synthetic(const std::string& json_text) {
  const nlohmann::json j = nlohmann::json::parse(json_text, nullptr, false);
  return !j.is_discarded() && large_synthetic(j);
}

}  // namespace ivr::fuzz
