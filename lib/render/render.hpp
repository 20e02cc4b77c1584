// render.hpp — internal: the render operation of a session, the one-shot session behind the
// one-shot functions, images downloaded from the device, and the CPU packet render (render.cl with
// IVR_RAYS rays per work-item in vector lanes), which renders and also marches the adjoint
// kernel's primal.
#pragma once
#include "ivr/scene.hpp"
#include "runtime/launch.hpp"
#include "runtime/runtime.hpp"
#include "runtime/variants.hpp"
#include "session/session.hpp"

namespace ivr {

// Rays per work-item; whether a device renders in packets (CPU devices, every integrator;
// $IVR_PACKET=0: never) and whether the adjoint takes its primal from one
// (emission–absorption, midpoint, no skipping); the packet configuration (primal: each pixel's
// emitted C and transmittance T into the image buffer, for the adjoint kernel, instead of the
// composited pixel); its launch.
int packet_lanes(Precision precision);
bool use_packet(const Device::Impl& dev);
bool use_packet_primal(const Device::Impl& dev, const RenderVariant& v);
KernelConfig packet_config(const RenderVariant& variant, bool primal);
PixelLaunch packet_launch(Device::Impl& dev, const cl::Kernel& kernel, const Scene& scene,
                          Precision precision);

// The tile of pixels one work-item of `lanes` rays covers (kernels/rays.cl, IVR_PACKET_W and
// IVR_PACKET_H): 4×4 for 16, 4×2 for 8, one pixel for one ray — a ray list's one row: runs of
// `lanes` rays; and the work-items that cover a width × height image.
struct PacketShape {
  int w = 1, h = 1;
  int across(int width) const { return (width + w - 1) / w; }
  int down(int height) const { return (height + h - 1) / h; }
};
PacketShape packet_shape(int lanes, bool ray_list = false);

// The image (in the session's precision) and, where `samples` is set, the per-pixel sample
// counts into it.
DeviceArray enqueue_render(Session::Impl& s, OperationRecord& op);

// An array's values on the host, downloaded once: as float32 in `floats`, and for a float64
// array also unrounded in `doubles` (left empty otherwise).
void download_kept(const DeviceArray& a, std::vector<float>* floats, std::vector<double>* doubles);
// An image array (views, H, W, C) as an Image, pixels_f64 filled for a float64 one.
Image image_of(const DeviceArray& image);

// A session over `scene` for one call of a one-shot function (render(), gradient(), …): the
// scene outlives it, so its host densities may serve the host-side grid. Throws like
// validate_with where the scene's volume lacks its data.
Session one_shot_session(Device& device, const Scene& scene, const SessionOptions& options);

}  // namespace ivr
