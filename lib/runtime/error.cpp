// error.cpp — names of ivr's status codes.
#include "ivr/error.hpp"

namespace ivr {

const char* status_name(Status status) {
  switch (status) {
    case Status::ok:
      return "ok";
    case Status::invalid_argument:
      return "invalid_argument";
    case Status::io:
      return "io";
    case Status::no_device:
      return "no_device";
    case Status::opencl:
      return "opencl";
    case Status::build:
      return "build";
    case Status::out_of_memory:
      return "out_of_memory";
    case Status::unsupported:
      return "unsupported";
  }
  return "unknown";
}

}  // namespace ivr
