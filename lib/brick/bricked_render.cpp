// bricked_render.cpp — the out-of-core render: plan, brick order, streaming, sweeps.
#include "brick/bricked_render.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <numeric>

#include "brick/domain.hpp"
#include "ivr/error.hpp"
#include "ivr/tf_parameters.hpp"
#include "render/render.hpp"
#include "runtime/real_args.hpp"
#include "session/session.hpp"

namespace ivr {

namespace {

constexpr int kStateReals = kBrickStateReals, kStateUints = kBrickStateUints;
// Runs of views up to this long launch each view over its brick's pixels alone (brick_pixels);
// longer ones launch once over every pixel of the run.
constexpr int kCulledViews = 16;
enum Phase { kBegin = 0, kMarch = 1, kFinish = 2, kSegmentBegin = 5 };

// The cameras or rays, their parameters and the TF on the device (bounds), and a little for the
// session's one-byte buffers.
std::uint64_t geometry_bytes(const Scene& scene, std::size_t real_size) {
  const std::size_t tf_rows =
      std::max({scene.tf.points.size(), scene.tf.entries.size(), scene.tf.gaussians.size()}) + 1;
  return (64 * scene.cameras.size() + RayList::kColumns * scene.rays.count() + 8 * tf_rows) *
             real_size +
         1024;
}

// Bricks in an order that every ray of the views with this key meets front to back: by the sum
// over axes of the distance from `eye` (the brick a perspective eye lies in, clamped to the grid;
// for an orthographic view the corner the rays come from). Along a ray each axis's brick index
// moves away from the eye's, so that sum grows at every brick face the ray crosses.
std::vector<int> front_to_back(const BrickLayout& l, const std::array<int, 3>& eye) {
  std::vector<int> order(l.total());
  std::iota(order.begin(), order.end(), 0);
  auto distance = [&](int b) {
    const std::array<int, 3> i = l.index(b);
    return std::abs(i[0] - eye[0]) + std::abs(i[1] - eye[1]) + std::abs(i[2] - eye[2]);
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return distance(a) < distance(b); });
  return order;
}

// The eye brick of a point in world space.
std::array<int, 3> eye_brick(const Scene& scene, const BrickLayout& l, const glm::dvec3& p) {
  const glm::dvec3 h = scene.voxel_size();
  std::array<int, 3> e{};
  for (int a = 0; a < 3; ++a) {
    const double u = (p[a] - scene.box_min[a]) / h[a] - 0.5 - (a == 2 ? l.z_first : 0);
    const double k = std::floor(u / l.edge);
    e[a] = int(std::clamp(std::isfinite(k) ? k : 0.0, 0.0, double(l.count[a] - 1)));
  }
  return e;
}

std::vector<ViewGroup> view_groups(const Scene& scene, const BrickLayout& l) {
  std::vector<std::array<int, 3>> keys;
  if (scene.has_ray_list()) {
    glm::dvec3 mean(0.0);
    const std::size_t n = scene.rays.count();
    for (std::size_t r = 0; r < n; ++r)
      mean += glm::dvec3(scene.rays.values[r * 8], scene.rays.values[r * 8 + 1],
                         scene.rays.values[r * 8 + 2]);
    keys.push_back(eye_brick(scene, l, mean / double(std::max<std::size_t>(n, 1))));
  } else {
    for (const Camera& c : scene.cameras) {
      if (c.projection == Projection::orthographic) {
        const glm::dvec3 d = c.target - c.eye;
        keys.push_back({d.x >= 0 ? 0 : l.count[0] - 1, d.y >= 0 ? 0 : l.count[1] - 1,
                        d.z >= 0 ? 0 : l.count[2] - 1});
      } else {
        keys.push_back(eye_brick(scene, l, c.eye));
      }
    }
  }
  std::map<std::array<int, 3>, ViewGroup> groups;
  for (int v = 0; v < int(keys.size()); ++v) {
    ViewGroup& g = groups[keys[v]];
    if (!g.runs.empty() && g.runs.back().first + g.runs.back().second == v)
      ++g.runs.back().second;
    else
      g.runs.push_back({v, 1});
  }
  std::vector<ViewGroup> out;
  for (auto& [key, g] : groups) {
    g.order = front_to_back(l, key);
    out.push_back(std::move(g));
  }
  return out;
}

// The pixels of `view` whose rays can meet brick b: the bounding rectangle of its corners
// projected (a camera ray meets a convex brick only through its projection), two pixels wider for
// rounding; the whole image where a corner lies behind a perspective eye, or for a ray list. Only
// the work spared depends on it: a ray it left out stays pending and the next sweep takes every
// pixel (render_bricked).
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) × [y0, y1)
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

PixelRect brick_pixels(const Scene& scene, const BrickLayout& l, int b, int view) {
  const ImageExtent e = image_extent(scene);
  const PixelRect all{0, 0, e.width, e.height};
  if (scene.has_ray_list()) return all;
  const Camera& c = scene.cameras[view];
  const glm::dvec3 h = scene.voxel_size();
  const std::array<double, 3> lo = l.lo(b), hi = l.hi(b);
  glm::dvec3 wlo, whi;
  for (int a = 0; a < 3; ++a) {
    wlo[a] = std::isfinite(lo[a]) ? scene.box_min[a] + (lo[a] + 0.5) * h[a] : scene.box_min[a];
    whi[a] = std::isfinite(hi[a]) ? scene.box_min[a] + (hi[a] + 0.5) * h[a] : scene.box_max[a];
  }
  const glm::dvec3 fwd = glm::normalize(c.target - c.eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, c.up));
  const glm::dvec3 up = glm::cross(right, fwd);
  const double aspect = double(e.width) / e.height;
  const bool ortho = c.projection == Projection::orthographic;
  const double half_h =
      ortho ? c.ortho_height / 2 : std::tan(c.fov_y * 3.14159265358979323846 / 360);
  double sx0 = INFINITY, sx1 = -INFINITY, sy0 = INFINITY, sy1 = -INFINITY;
  for (int k = 0; k < 8; ++k) {
    const glm::dvec3 p((k & 1) ? whi.x : wlo.x, (k & 2) ? whi.y : wlo.y, (k & 4) ? whi.z : wlo.z);
    const glm::dvec3 d = p - c.eye;
    double depth = 1;
    if (!ortho) {
      depth = glm::dot(d, fwd);
      if (!(depth > 1e-6 * glm::length(d))) return all;
    }
    const double sx = glm::dot(d, right) / (depth * half_h * aspect);
    const double sy = glm::dot(d, up) / (depth * half_h);
    sx0 = std::min(sx0, sx), sx1 = std::max(sx1, sx), sy0 = std::min(sy0, sy),
    sy1 = std::max(sy1, sy);
  }
  // Pixel x's centre is at sx = (2x + 1)/W − 1; row y's at sy = 1 − (2y + 1)/H.
  auto clampi = [](double v, int n) { return int(std::clamp(v, 0.0, double(n))); };
  PixelRect r;
  r.x0 = clampi(std::floor((sx0 + 1) * e.width / 2 - 0.5) - 2, e.width);
  r.x1 = clampi(std::ceil((sx1 + 1) * e.width / 2 - 0.5) + 3, e.width);
  r.y0 = clampi(std::floor((1 - sy1) * e.height / 2 - 0.5) - 2, e.height);
  r.y1 = clampi(std::ceil((1 - sy0) * e.height / 2 - 0.5) + 3, e.height);
  return r;
}

}  // namespace

int count_from_env(const char* name, int most, const char* what) {
  const char* env = std::getenv(name);
  if (!env || !*env) return 0;
  char* end = nullptr;
  const long v = std::strtol(env, &end, 10);
  if (end == env || *end || v < 1 || v > most)
    throw Error(Status::invalid_argument, std::string(name) + ": '" + env + "' is not " + what);
  return int(v);
}

int volume_brick_from_env() {
  return count_from_env("IVR_VOLUME_BRICK", 1 << 24, "a brick edge (cells, an integer ≥ 1)");
}

BrickPlan plan_render(Device& device, const Scene& scene, Precision precision, int forced_edge,
                      bool gradient, int halo) {
  BrickPlan plan;
  const DeviceInfo& info = device.info();
  const std::size_t real_size = precision == Precision::f64 ? 8 : 4;
  const std::uint64_t rays = image_extent(scene).pixels();
  const std::uint64_t voxels = scene.volume.voxel_count();
  const std::uint64_t image = rays * (scene.channels() * real_size + 4);
  const std::uint64_t geometry = geometry_bytes(scene, real_size);
  plan.budget = brick_budget(device);
  // The gradient adds the volume's gradient (in core), or per ray its pixel adjoints (8 reals), the
  // target and its loss and background terms (4 reals), the TF's gradient, and two slots of a
  // brick's gradient (out of core: lib/brick/bricked_gradient.cpp).
  const std::vector<std::size_t> tf_shape = tf_gradient_shape(scene.tf);
  const std::uint64_t target =
      gradient ? (rays * (scene.channels() + 4) + tf_shape[0] * tf_shape[1]) * real_size : 0;
  plan.in_core_bytes = (gradient ? 2 : 1) * voxels * real_size + image + geometry + target;
  if (forced_edge <= 0) forced_edge = volume_brick_from_env();
  if (forced_edge <= 0 && (plan.budget == 0 || plan.in_core_bytes <= plan.budget)) return plan;
  const std::uint64_t fixed =
      image + geometry + target +
      rays * ((kStateReals + (gradient ? 8 : 0)) * real_size + kStateUints * 4) + 64;
  const int extra_slots = gradient ? 2 : 0;  // two slots of a brick's gradient
  const int longest = std::max({scene.volume.nx, scene.volume.ny, scene.volume.nz});
  auto fits = [&](int edge, int slots) {
    const BrickLayout l =
        brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, edge, 0, -1, halo);
    const std::uint64_t slot = l.largest_voxels() * real_size;
    return slot <= info.max_allocation &&
           fixed + std::uint64_t(slots + extra_slots) * slot <= plan.budget;
  };
  int edge = forced_edge;
  if (edge <= 0) {
    edge = 1;
    while (edge * 2 < longest && fits(edge * 2, 2)) edge *= 2;
  }
  plan.layout = brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, edge, 0, -1, halo);
  const std::uint64_t slot = plan.layout.largest_voxels() * real_size;
  const int wanted = std::min(plan.layout.total(), 2);
  // Where not even the image and the per-ray state fit, bricks cannot help: the in-core render
  // reports what does not fit (unless bricks were asked for).
  if (plan.budget && !fits(edge, wanted) && forced_edge <= 0)
    return BrickPlan{{}, 0, plan.budget, plan.in_core_bytes, 0};
  if (plan.budget && !fits(edge, wanted))
    throw Error(Status::out_of_memory,
                "out-of-core render: bricks of " + std::to_string(edge) + " cells (" +
                    memory_text(slot) + " each) and the per-ray state (" + memory_text(fixed) +
                    ") do not fit the device-memory budget of " + memory_text(plan.budget) +
                    (device_memory_limit_from_env() ? " (IVR_DEVICE_MEMORY_LIMIT)" : ""));
  const std::uint64_t room =
      plan.budget ? (plan.budget - fixed) / slot - extra_slots : plan.layout.total();
  plan.slots = int(std::clamp<std::uint64_t>(room, wanted, plan.layout.total()));
  plan.bricked_bytes = fixed + std::uint64_t(plan.slots + extra_slots) * slot;
  return plan;
}

BrickedMarch::BrickedMarch(Device& device, const Scene& scene, const RenderOptions& options,
                           const BrickPlan& plan, const char* operation)
    : scene_(scene),
      plan_(plan),
      session_(std::make_unique<Session::Impl>(
          device, description_of(scene),
          SessionOptions{options.precision, options.step, EmptySpace::off,
                         options.min_empty_fraction, options.brick_size},
          false)),
      s(session_.impl()),
      op(s.begin(operation)),
      e_(image_extent(scene)),
      stream_(s.dev, plan.slots, plan.layout.largest_voxels() * s.real_size) {
  const BrickLayout& l = plan.layout;
  const std::size_t held = l.held();
  if (scene.volume.data.size() != held)
    throw Error(Status::invalid_argument,
                "volume: holds " + std::to_string(scene.volume.data.size()) + " values but " +
                    (held == scene.volume.voxel_count()
                         ? "dims need " + std::to_string(held)
                         : "planes " + std::to_string(l.data_first) + ".." + std::to_string(l.data_last) +
                               " need " + std::to_string(held)));
  if (scene.integrator.tolerance > 0 && !(options.step > 0))
    throw Error(Status::unsupported,
                "out-of-core: integrator.tolerance chooses its step from the whole volume; "
                "give the step (--step) for a bricked volume");
  Device::Impl& dev = s.dev;
  const Integrator& integrator = s.integrator();
  variant = s.variant_of(integrator);
  variant.empty_space = false;
  const std::size_t rays = e_.pixels();
  state_ = dev.buffer(CL_MEM_READ_WRITE, rays * kStateReals * s.real_size, nullptr,
                      "the bricked march's per-ray state");
  state_u_ = dev.buffer(CL_MEM_READ_WRITE, rays * kStateUints * 4, nullptr,
                        "the bricked march's per-ray counters");
  image = s.output("image", s.image_shape(), real_dtype(s.f64), "the image");
  samples = dev.buffer(CL_MEM_READ_WRITE, rays * 4, nullptr, "the sample counts");
  const cl_uint zero = 0;
  pending_ =
      dev.buffer(CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, 4, &zero, "the pending-ray count");
  const KernelConfig config = variant.config("bricked.cl", "bricked_render");
  op.stats.variant = config.label();
  render_ = &s.kernels.get(config, &op.stats.build_seconds);
  a0_ = arguments(*render_);
  if (use_packet(dev) && variant.scheme != Scheme::exact) {  // (exact: pieces, one ray an item)
    const int lanes = lanes_ = packet_lanes(variant.precision);
    const KernelConfig packet =
        variant.config("bricked_packet.cl", "bricked_render_packet").set(Switch::rays, lanes);
    march_packet_ = &s.kernels.get(packet, &op.stats.build_seconds);
    tile_ = packet_shape(lanes, scene.has_ray_list());
    arguments(*march_packet_);
    op.stats.variant = packet.label();
  }
  cl_call("setting the bricked render's arguments", [&] {
    for (cl::Kernel* k : {render_, march_packet_}) {
      if (!k) continue;
      k->setArg(a0_ + 6, buffer_of(image));
      k->setArg(a0_ + 7, samples);
      k->setArg(a0_ + 8, pending_);
    }
  });
  groups_ = view_groups(scene, plan.layout);
}

int BrickedMarch::arguments(cl::Kernel& k) {
  return cl_call("setting the bricked march's arguments", [&] {
    const int a = s.set_scene_args(k, s.integrator());
    k.setArg(a + 4, state_);
    k.setArg(a + 5, state_u_);
    return a;
  });
}

void BrickedMarch::set_brick(cl::Kernel& k, int b, int slot) {
  const BrickLayout& l = plan_.layout;
  const std::array<int, 3> o = l.origin(b), x = l.extent(b);
  const std::array<double, 3> lo = l.lo(b), hi = l.hi(b);
  k.setArg(0, stream_.buffer(slot));
  k.setArg(1, cl_int4{{x[0], x[1], x[2], 0}});
  set_real4(k, a0_ + 1, s.f64, lo[0], lo[1], lo[2]);
  set_real4(k, a0_ + 2, s.f64, hi[0], hi[1], hi[2]);
  k.setArg(a0_ + 3, cl_int4{{o[0], o[1], o[2], 0}});
}

void BrickedMarch::launch_all(cl::Kernel& k, int phase) {
  cl_call("running the bricked march on " + s.dev.info.name, [&] {
    set_brick(k, 0, 0);
    if (phase == kSegmentBegin) {  // the layout's planes along z (±∞ at the box faces): the slab
      const BrickLayout& l = plan_.layout;
      const int last = (l.count[2] - 1) * l.count[0] * l.count[1];
      set_real4(k, a0_ + 1, s.f64, -INFINITY, -INFINITY, l.lo(0)[2]);
      set_real4(k, a0_ + 2, s.f64, INFINITY, INFINITY, l.hi(last)[2]);
    }
    k.setArg(a0_, cl_int(phase));
    // A pass over the whole image, one ray per work-item, as the in-core one-ray render's: its
    // launch shape ("render"). (The "bricked" rows shape the sweeps' rectangles; their 1x1 on
    // PoCL doubled this pass's time: 4.6 against 2.2 ms for BEGIN at 256².)
    op.events.push_back(
        enqueue(s.dev, k, pixel_launch(s.dev, k, "render", e_.width, e_.height, e_.views, false)));
  });
}

int BrickedMarch::sweep(cl::Kernel& k, int phase, const BrickHooks& hooks, const char* tuning,
                        PacketShape tile) {
  const BrickLayout& l = plan_.layout;
  if (densities_f64 && densities_f64->size() != l.held())
    throw Error(Status::invalid_argument,
                "bricked march: " + std::to_string(densities_f64->size()) +
                    " float64 densities for the " + std::to_string(l.held()) + " held");
  auto fill = [&](int b, std::vector<unsigned char>& out) {
    if (densities_f64)
      extract_brick(densities_f64->data(), l, b, s.f64, out);
    else
      extract_brick(scene_.volume, l, b, s.f64, out);
  };
  Device::Impl& dev = s.dev;
  int sweeps = 0;
  cl_call("running the bricked march on " + dev.info.name, [&] {
    if (before_sweeps) before_sweeps();
    for (;;) {
      ++sweeps;
      for (const ViewGroup& g : groups_)
        for (int b : g.order) {
          const int i = stream_.resident(b, fill);
          set_brick(k, b, i);
          std::vector<cl::Event> wait{stream_.ready(i)};
          if (hooks.before) hooks.before(b, wait);
          k.setArg(a0_, cl_int(phase));
          std::vector<cl::Event> marched;
          auto march = [&](const PixelRect& r, int first, int count) {
            if (r.empty()) return;
            // In work-items: tiles of tile.w × tile.h pixels.
            const int x0 = r.x0 / tile.w, y0 = r.y0 / tile.h;
            const int x1 = tile.across(r.x1), y1 = tile.down(r.y1);
            // Explicit work-groups (the database's, else 8x8), rounded up past the rectangle (the
            // kernels skip what lies outside the image, and a pixel the brick does not hold is
            // left as it was): the driver's choice for a small rectangle can be one group, which
            // one thread of a CPU marches alone.
            cl::Event ev;
            if (hooks.launch) {
              ev = hooks.launch(TileRect{x0, y0, x1 - x0, y1 - y0, first, count}, wait);
            } else {
              const PixelLaunch shape = pixel_launch(dev, k, tuning, x1 - x0, y1 - y0, count, true);
              ev = enqueue(dev, k, shape, cl::NDRange(x0, y0, first), &wait);
            }
            op.events.push_back(ev);
            stream_.used(i, ev);
            marched.push_back(ev);
          };
          for (const auto& [first, count] : g.runs) {
            if (sweeps > 1 || count > kCulledViews) {  // every pixel
              march(PixelRect{0, 0, e_.width, e_.height}, first, count);
              continue;
            }
            for (int v = first; v < first + count; ++v) march(brick_pixels(scene_, l, b, v), v, 1);
          }
          dev.queue.flush();
          if (hooks.after) hooks.after(b, marched);
        }
      if (after_sweep) after_sweep();
      const cl_uint zero = 0;
      dev.queue.enqueueWriteBuffer(pending_, CL_FALSE, 0, 4, &zero);
      launch_all(*render_, kFinish);
      cl_uint left = 0;
      dev.queue.enqueueReadBuffer(pending_, CL_TRUE, 0, 4, &left);
      if (left == 0) break;
      if (sweeps > (l.total() + 1) * workers)
        throw Error(Status::opencl, "out-of-core march: " + std::to_string(left) +
                                        " rays still marching after " + std::to_string(sweeps) +
                                        " sweeps over the bricks");
    }
  });
  op.stats.sweeps += sweeps;
  return sweeps;
}

void BrickedMarch::begin() {
  launch_all(*render_, segments ? kSegmentBegin : kBegin);
}

void BrickedMarch::render() {
  begin();
  if (march_packet_)
    sweep(*march_packet_, kMarch, {}, "bricked_packet", tile_);
  else
    sweep(*render_, kMarch, {}, "bricked");
  // The last sweep's FINISH, which counted no pending ray, wrote the image from the final states.
  mark_written(image, op.events.back());
  op.samples = samples;
  op.sample_count = e_.pixels();
  op.stats.step = s.integrator().step;
  op.stats.bricks = plan_.layout.total();
  op.stats.device_bytes = plan_.bricked_bytes;
}

Image render_bricked(Device& device, const Scene& scene, const RenderOptions& options,
                     const BrickPlan& plan, RenderStats* stats, const DomainPart* domain,
                     DomainStats* domain_stats) {
  BrickedMarch march(device, scene, options, plan, "render");
  if (domain) attach_exchange(march, *domain, domain_stats);
  march.render();
  const Image out = image_of(march.image);
  bricked_render_stats(march, plan, stats);
  return out;
}

void bricked_render_stats(BrickedMarch& march, const BrickPlan& plan, RenderStats* stats) {
  if (stats) {
    const OperationStats st = march.session().last_stats();
    stats->kernel_seconds = st.kernel_seconds;
    stats->build_seconds = st.build_seconds;
    stats->samples = st.samples;
    stats->variant = st.variant;
    stats->scheme = scheme_name(march.s.integrator().scheme);
    stats->step = st.step;
    stats->device_bytes = st.device_bytes;
    stats->bricks = plan.layout.total();
    stats->brick_edge = plan.layout.edge;
    stats->sweeps = st.sweeps;
    stats->uploaded_bytes = march.stream().uploaded_bytes;
    stats->brick_uploads = march.stream().uploads;
  }
}

}  // namespace ivr
