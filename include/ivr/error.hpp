// ivr/error.hpp — the one exception type of ivr, with a status code the C API maps one-to-one.
#pragma once
#include <stdexcept>
#include <string>

#include "ivr/export.h"

namespace ivr {

enum class Status {
  ok = 0,
  invalid_argument = 1,  // bad scene, bad option, bad array
  io = 2,                // missing, unreadable or malformed file
  no_device = 3,         // no OpenCL platform or no device matches the selector
  opencl = 4,            // an OpenCL call failed
  build = 5,             // a kernel failed to compile; the message carries the build log
  out_of_memory = 6,     // host or device allocation failed or would exceed the device's limits
  unsupported = 7,       // the device or build lacks a feature (e.g. fp64)
};

// Name of a status, e.g. "invalid_argument".
IVR_API const char* status_name(Status status);

class IVR_API Error : public std::runtime_error {
 public:
  Error(Status status, const std::string& message, int opencl_code = 0)
      : std::runtime_error(message), status_(status), opencl_code_(opencl_code) {}
  Status status() const noexcept { return status_; }
  // The OpenCL error code behind the error (negative), 0 where none.
  int opencl_code() const noexcept { return opencl_code_; }

 private:
  Status status_;
  int opencl_code_;
};

}  // namespace ivr
