// variants.hpp — "model only what a scene needs": the scene's features a marching kernel is
// compiled for, written into its kernel configuration (runtime/kernel_config.hpp).
#pragma once

#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "runtime/kernel_config.hpp"

namespace ivr {

struct RenderVariant {
  Model model = Model::emission_absorption;
  TfKind tf = TfKind::identity;
  Scheme scheme = Scheme::midpoint;
  Precision precision = Precision::f32;
  bool early_termination = true;
  bool empty_space = false;  // empty-space skipping
  int brick_size = 8;
  bool ray_list = false;  // the scene's rays are a list (kernels/geometry.cl, IVR_RAY_LIST)

  static RenderVariant of(const Scene& scene, const Integrator& integrator, Precision precision);
  // Sets the configuration's model, TF, scheme, precision, early termination and skipping.
  KernelConfig& apply(KernelConfig& config) const;
  KernelConfig config(const std::string& file, const std::string& entry) const {
    KernelConfig c(file, entry);
    return apply(c);
  }
};

}  // namespace ivr
