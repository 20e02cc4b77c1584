// options.hpp — the C API's option structs to and from the core's option structs, field by field
// from one table per struct (lib/capi/options/*.def), reading only the fields a caller's struct
// has (its size field: structs may grow at their end without breaking callers).
#pragma once
#include <cstddef>
#include <functional>
#include <string>

#include "ivr/ivr.h"
#include "ivr/ivr_session.h"
#include "ivr/reconstruct.hpp"
#include "ivr/session.hpp"
#include "ivr/tomo.hpp"
#include "ivr/viewpoint.hpp"

namespace ivr::capi {

// The C struct with the core's defaults (size set).
ivr_tomo_options c_options(const ivr::TomoOptions& o);
ivr_reconstruct_options c_options(const ivr::ReconstructOptions& o);
ivr_viewpoint_options c_options(const ivr::ViewpointOptions& o);
ivr_session_options c_options(const ivr::SessionOptions& o);

// The core's options from a caller's C struct (NULL: the defaults); fields beyond its size keep
// the core's defaults. Throws CError(invalid_argument) for a size too small to be a struct filled
// by its init function, or an enum value outside its type, naming the field.
ivr::TomoOptions core_options(const ivr_tomo_options* c);
ivr::ReconstructOptions core_options(const ivr_reconstruct_options* c);
ivr::ViewpointOptions core_options(const ivr_viewpoint_options* c);
ivr::SessionOptions core_options(const ivr_session_options* c);

// For the tests of the tables: every field of a struct in order, with its offset and size.
struct OptionField {
  std::string name;
  std::size_t offset, size;
};
void each_option_field(const char* c_struct, const std::function<void(const OptionField&)>& f);

}  // namespace ivr::capi
