// variants.cpp — scene feature set → kernel variant (preamble and label).
#include "variants.hpp"

#include <sstream>

namespace ivr {

const char* tf_kind_name(TfKind kind) {
  switch (kind) {
    case TfKind::identity:
      return "identity";
    case TfKind::piecewise_linear:
      return "piecewise_linear";
    case TfKind::table:
      return "table";
    case TfKind::gaussian:
      return "gaussian";
  }
  return "?";
}

RenderVariant RenderVariant::of(const Scene& scene, const Integrator& integrator,
                                Precision precision) {
  RenderVariant v;
  v.model = scene.model;
  v.tf = scene.tf.kind;
  v.scheme = integrator.scheme;
  v.precision = precision;
  v.early_termination = integrator.min_transmittance > 0;
  return v;
}

std::string RenderVariant::preamble() const {
  std::ostringstream s;
  s << "#define IVR_MODEL " << (model == Model::absorption ? 0 : 1) << "\n"
    << "#define IVR_TF " << int(tf) << "\n"
    << "#define IVR_SCHEME " << int(scheme) << "\n"
    << "#define IVR_F64 " << (precision == Precision::f64 ? 1 : 0) << "\n"
    << "#define IVR_EARLY_TERMINATION " << (early_termination ? 1 : 0) << "\n"
    << "#define IVR_SKIP_EMPTY " << (skip_empty ? 1 : 0) << "\n"
    << "#define IVR_BRICK_SIZE " << brick_size << "\n";
  return s.str();
}

std::string RenderVariant::label() const {
  std::ostringstream s;
  s << "render model=" << (model == Model::absorption ? "absorption" : "emission_absorption")
    << " tf=" << tf_kind_name(tf) << " scheme=" << scheme_name(scheme) << " "
    << (precision == Precision::f64 ? "f64" : "f32")
    << " ert=" << (early_termination ? "on" : "off") << " skip=" << (skip_empty ? "on" : "off");
  return s.str();
}

}  // namespace ivr
