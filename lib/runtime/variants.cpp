// variants.cpp — scene feature set → the marching kernels' switches.
#include "runtime/variants.hpp"

namespace ivr {

RenderVariant RenderVariant::of(const Scene& scene, const Integrator& integrator,
                                Precision precision) {
  RenderVariant v;
  v.model = scene.model;
  v.tf = scene.tf.kind;
  v.scheme = integrator.scheme;
  v.precision = precision;
  v.early_termination = integrator.min_transmittance > 0;
  v.ray_list = scene.has_ray_list();
  return v;
}

KernelConfig& RenderVariant::apply(KernelConfig& c) const {
  return c.set(Switch::model, model == Model::absorption ? 0 : 1)
      .set(Switch::tf, int(tf))
      .set(Switch::scheme, int(scheme))
      .with_precision(precision)
      .set(Switch::early_termination, early_termination)
      .set(Switch::empty_space, empty_space)
      .set(Switch::brick_size, brick_size)
      .set(Switch::ray_list, ray_list);
}

}  // namespace ivr
