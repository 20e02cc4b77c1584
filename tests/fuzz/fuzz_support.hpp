// fuzz_support.hpp — what every loader's fuzz harness shares: a scratch folder of its own, the
// input written there as a file, and the rule under test: bad bytes may raise ivr::Error (a clear
// error) and nothing else — any other exception, crash, hang or oversized allocation is a bug.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

#include "ivr/error.hpp"

namespace ivr::fuzz {

// This process's folder ($TMPDIR or /tmp, ivr-fuzz-<pid>), made at first use, removed at exit.
const std::string& scratch();

// Writes bytes to scratch()/name and returns the path.
std::string put(const std::string& name, const std::uint8_t* data, std::size_t size);
std::string put(const std::string& name, const std::string& text);

// True when the JSON text asks for a synthetic volume of more than 2^21 voxels anywhere: such a
// volume is made at the size asked (a request, not a size claimed by a file), so the harnesses
// leave those inputs out rather than allocate gigabytes.
bool asks_for_large_synthetic(const std::string& json_text);

// Runs f; an ivr::Error is the expected outcome of bad input, anything else escapes.
template <class F>
void clean(F&& f) {
  try {
    f();
  } catch (const ivr::Error&) {
  }
}

}  // namespace ivr::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
