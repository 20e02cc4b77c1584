// kernel_sources.hpp — the kernels' text: embedded at build time, or read from $IVR_KERNEL_DIR.
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace ivr {
namespace detail {
const std::vector<std::pair<std::string, std::string>>& embedded_kernels();
}

// Text of kernels/<name>: from $IVR_KERNEL_DIR when that is set (kernel development), else the
// copy embedded in the library. Throws ivr::Error(io) if there is no such kernel file.
std::string kernel_file(const std::string& name);

// kernels/<name> with each `#include "x.cl"` replaced by x.cl's text, every file at most once,
// so that the files stay real OpenCL sources that also compile offline with -I kernels.
std::string assemble_kernel(const std::string& name);

}  // namespace ivr
