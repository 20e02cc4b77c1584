// render_packet.hpp — internal: the CPU packet render (kernels/render_packet.cl), which renders and
// also marches the adjoint kernel's primal (lib/adjoint/adjoint.cpp).
#pragma once
#include "ivr/scene.hpp"
#include "runtime/launch.hpp"
#include "runtime/runtime.hpp"
#include "runtime/variants.hpp"

namespace ivr {

// Rays per work-item; whether a scene's variant takes the packet kernel (CPU device,
// emission–absorption, midpoint, piecewise-linear TF, float32, no skipping; $IVR_PACKET=0:
// never); its configuration (primal: each pixel's emitted C and transmittance T into the image
// buffer, for the adjoint kernel, instead of the composited pixel); its launch.
int packet_lanes();
bool use_packet(const Device::Impl& dev, const Scene& scene, const RenderVariant& v);
KernelConfig packet_config(const RenderVariant& variant, bool primal);
PixelLaunch packet_launch(Device::Impl& dev, const cl::Kernel& kernel, const Scene& scene);

}  // namespace ivr
