// bricked_gradient.cpp — the out-of-core density gradient.
#include "brick/bricked_gradient.hpp"

#include "brick/domain.hpp"
#include "ivr/error.hpp"
#include "runtime/real_args.hpp"

namespace ivr {

namespace {
constexpr int kAdjointBegin = 3, kAdjointMarch = 4;  // kernels/bricked.cl
constexpr int kAdjointReals = 8;
}  // namespace

Gradient gradient_bricked(Device& device, const Scene& scene, const Image& target,
                          const std::vector<std::string>& groups, const GradientOptions& o,
                          const BrickPlan& plan, const DomainPart* domain,
                          DomainStats* domain_stats) {
  const std::string where = "out-of-core gradient (the volume is split into " +
                            std::to_string(plan.bricks()) + " bricks; docs/scaling.md)";
  if (groups != std::vector<std::string>{"density"})
    throw Error(Status::unsupported, where + ": only --wrt density so far");
  if (scene.integrator.scheme != Scheme::midpoint)
    throw Error(Status::unsupported,
                where + ": only the midpoint scheme so far, not " + scheme_name(scene.integrator.scheme));
  if (o.mode == Mode::forward)
    throw Error(Status::unsupported, where + ": adjoint mode only");
  RenderOptions ro;
  ro.precision = o.precision;
  ro.step = o.step;
  BrickedMarch march(device, scene, ro, plan, "gradient");
  if (domain) attach_exchange(march, *domain, domain_stats);
  Session::Impl& s = march.s;
  march.session().set_target(target);
  march.render();

  const BrickLayout& l = plan.layout;
  const ImageExtent e = image_extent(scene);
  const std::size_t rays = e.pixels();
  Device::Impl& dev = s.dev;
  KernelConfig config = march.variant.config("bricked.cl", "bricked_adjoint");
  config.set(Switch::loss_l1, o.loss == Loss::l1).set(Switch::loss_dot, o.loss == Loss::dot);
  config.with_atomics(atomic_add_for(dev.info, s.f64));
  cl::Kernel& k = s.kernels.get(config, &march.op.stats.build_seconds);
  const int a0 = march.arguments(k);
  const cl::Buffer adj = dev.buffer(CL_MEM_READ_WRITE, rays * kAdjointReals * s.real_size, nullptr,
                                    "the per-ray pixel adjoints");
  const cl::Buffer pixel_loss =
      dev.buffer(CL_MEM_READ_WRITE, rays * s.real_size, nullptr, "the per-pixel loss");
  const std::size_t slot_bytes = l.largest_voxels() * s.real_size;
  const cl::Buffer grad =
      dev.buffer(CL_MEM_READ_WRITE, slot_bytes, nullptr, "a brick's density gradient");
  cl_call("setting the bricked adjoint's arguments", [&] {
    k.setArg(a0 + 4 + 2, adj);
    k.setArg(a0 + 4 + 3, buffer_of(s.target));
    set_real(k, a0 + 4 + 4, s.f64, 1.0 / double(rays * scene.channels()));
    k.setArg(a0 + 4 + 5, pixel_loss);
    k.setArg(a0 + 4 + 6, grad);
  });
  march.launch_all(k, kAdjointBegin);

  const std::size_t planes = std::size_t(l.z_last - l.z_first + 1);  // all, or a worker's slab
  std::vector<double> gradient(planes * l.dims[1] * l.dims[0], 0.0);
  std::vector<unsigned char> host;
  BrickHooks hooks;
  hooks.before = [&](int b, std::vector<cl::Event>& wait) {
    cl::Event zeroed;
    dev.queue.enqueueFillBuffer(grad, cl_uchar(0), 0, l.voxels(b) * s.real_size, nullptr, &zeroed);
    wait.push_back(zeroed);
  };
  hooks.after = [&](int b, const std::vector<cl::Event>& marched) {
    if (marched.empty()) return;
    host.resize(l.voxels(b) * s.real_size);
    dev.queue.enqueueReadBuffer(grad, CL_TRUE, 0, host.size(), host.data(), &marched);
    add_brick(host, l, b, s.f64, gradient.data());
  };
  march.sweep(k, kAdjointMarch, hooks);

  const std::vector<double> losses = download_reals(dev, s.f64, pixel_loss, rays);
  Gradient d;
  for (double v : losses) d.loss += v;
  d.step = s.integrator().step;
  d.plan.mode = Mode::adjoint;
  d.plan.model = "out of core";
  d.groups.push_back({"density",
                      {planes, std::size_t(scene.volume.ny), std::size_t(scene.volume.nx)},
                      std::move(gradient)});
  d.parameters = d.groups[0].values.size();
  const OperationStats st = march.session().last_stats();
  d.kernel_seconds = st.kernel_seconds;
  d.device_bytes = plan.bricked_bytes;
  d.bricks = plan.bricks();
  d.atomics = atomic_add_name(atomic_add_for(dev.info, s.f64));
  return d;
}

}  // namespace ivr
