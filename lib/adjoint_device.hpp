// adjoint_device.hpp — the adjoint gradient of a volume that stays on the device: what the
// reconstruction loop calls every iteration (no volume upload, no gradient read-back).
#pragma once
#include "ivr/gradient.hpp"
#include "runtime.hpp"

namespace ivr {

// As ivr::gradient with `integrator` already chosen and the scene validated by the caller, but
// the densities come from `volume` (Real of options.precision, the scene's shape; scene.volume.data
// is not read) and, with options.density, the density gradient is left in *density_out (a new
// buffer of the same shape and precision) instead of Gradient::density. With options.deterministic,
// *fixed_exponent (optional) carries the fixed-point scale from call to call: the previous
// call's measured scale in (kUnknownExponent: none, and a first pass measures it), this call's
// out — one pass per call while the gradient's size changes slowly.
constexpr int kUnknownExponent = -1000000;
Gradient gradient_on_device(Device::Impl& dev, const Scene& scene, const Integrator& integrator,
                            const Image& target, const GradientOptions& options,
                            const cl::Buffer& volume, cl::Buffer* density_out,
                            int* fixed_exponent = nullptr);

}  // namespace ivr
