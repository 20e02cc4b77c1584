// variants.hpp — "model only what a scene needs": the feature set a kernel is compiled for, and
// the generated #define preamble that selects it.
#pragma once
#include <string>

#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

struct RenderVariant {
  Model model = Model::emission_absorption;
  TfKind tf = TfKind::identity;
  Scheme scheme = Scheme::midpoint;
  Precision precision = Precision::f32;
  bool early_termination = true;
  bool skip_empty = false;  // empty-space skipping (render only)
  int brick_size = 8;

  static RenderVariant of(const Scene& scene, const Integrator& integrator, Precision precision);
  std::string preamble() const;  // "#define IVR_MODEL 1\n..." for kernels/config.cl
  std::string label()
      const;  // "render model=emission_absorption tf=gaussian scheme=midpoint f32 ert=on skip=off"
};

const char* tf_kind_name(TfKind kind);

}  // namespace ivr
