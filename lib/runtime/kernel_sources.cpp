// kernel_sources.cpp — finds kernel files and resolves their #include lines.
#include "runtime/kernel_sources.hpp"

#include <cstdlib>
#include <set>
#include <sstream>

#include "io/files.hpp"
#include "ivr/error.hpp"

namespace ivr {

std::string kernel_file(const std::string& name) {
  if (const char* dir = std::getenv("IVR_KERNEL_DIR"); dir && *dir)
    return read_text_file(std::string(dir) + "/" + name, "kernel file");
  for (const auto& [file, text] : detail::embedded_kernels())
    if (file == name) return text;
  throw Error(Status::io, "no kernel file '" + name + "' is embedded in this build of ivr");
}

namespace {

void append_resolved(const std::string& name, std::set<std::string>& seen, std::string& out) {
  if (!seen.insert(name).second) return;
  std::istringstream lines(kernel_file(name));
  std::string line;
  while (std::getline(lines, line)) {
    const std::size_t hash = line.find_first_not_of(" \t");
    if (hash != std::string::npos && line.compare(hash, 8, "#include") == 0) {
      const std::size_t open = line.find('"'), close = line.rfind('"');
      if (open != std::string::npos && close > open) {
        append_resolved(line.substr(open + 1, close - open - 1), seen, out);
        continue;
      }
    }
    out += line;
    out += '\n';
  }
}

}  // namespace

std::string assemble_kernel(const std::string& name) {
  std::set<std::string> seen;
  std::string out;
  append_resolved(name, seen, out);
  return out;
}

}  // namespace ivr
