// rays.cpp — the ray-list suite: the projector pair (and the render) over a list of rays against
// the same rays as cameras' pixels, on device-resident data (issue 23's target: a ray-list
// projection ≥ 0.8× the throughput of the same number of camera rays), and the throughput of
// sightlines that end inside the volume (an observer at the centre, stars at random points).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <random>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

namespace {

// Every pixel of every camera as one list, view by view (the camera image's own order).
RayList rays_of_cameras(const std::vector<Camera>& cameras) {
  RayList all;
  for (const Camera& c : cameras) {
    const RayList one = ray_list_of_camera(c);
    all.values.insert(all.values.end(), one.values.begin(), one.values.end());
  }
  return all;
}

// `count` sightlines from the box centre to uniform random points of the box, seeded.
RayList sightlines(std::size_t count, const Scene& scene) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> points;
  points.reserve(count * 6);
  const glm::dvec3 lo = scene.box_min, hi = scene.box_max, centre = 0.5 * (lo + hi);
  for (std::size_t i = 0; i < count; ++i) {
    points.insert(points.end(), {centre.x, centre.y, centre.z});
    for (int k = 0; k < 3; ++k) points.push_back(lo[k] + (hi[k] - lo[k]) * u(rng));
  }
  return make_ray_list(points.data(), count, 6);
}

struct Timed {
  Measurement m;
  std::vector<double> first;  // the first run's result (the check's input)
};

// One resident operation of `session`: project (N x), backproject (Nᵀ y), the gradient of the
// loss against the session's target with respect to the rays themselves, or render.
DeviceArray run_op(Session& session, const std::string& op, const DeviceArray& x,
                   const DeviceArray& y) {
  if (op == "project") return session.project(x);
  if (op == "backproject") return session.backproject(y);
  if (op == "rays_gradient") {
    GradientRequest q;
    q.wrt = {"rays"};
    return session.gradient(q)["rays"];
  }
  return session.render();
}

// The operation timed (resident), with its first result for the check.
Timed time_op(Context& ctx, Session& session, const std::string& op, const DeviceArray& x,
              const DeviceArray& y, const Check& check) {
  Timed t;
  DeviceArray out = run_op(session, op, x, y);
  t.first = out.to_doubles();
  t.m = measure_resident(
      ctx.budget, session,
      [&] {
        out = run_op(session, op, x, y);
        out.wait();
      },
      [&] { return check.passed; });
  return t;
}

}  // namespace

void rays_suite(Context& ctx) {
  const std::vector<int> sizes = ctx.quick ? std::vector<int>{32} : std::vector<int>{64, 128};
  for (int n : sizes) {
    const int views = n / 2;
    const std::string base = "v" + std::to_string(n) + "_views" + std::to_string(views);
    if (!ctx.wants(base)) continue;
    std::cerr << "ivr-bench: rays/" << base << "...\n";
    Scene cameras = tomo_scene(n, views, false, 1);
    Scene list = cameras;
    list.rays = rays_of_cameras(cameras.cameras);
    list.cameras.clear();
    const std::size_t rays = list.rays.count();
    const nlohmann::json params = {{"volume", n},
                                   {"views", views},
                                   {"detector", n},
                                   {"beam", "parallel"},
                                   {"rays", rays}};
    Session sc(ctx.device, cameras), sl(ctx.device, list);
    const std::vector<double> xv = uniform(cameras.volume.voxel_count(), 1), yv = uniform(rays, 2);
    DeviceArray x(ctx.device, sc.volume_shape(), DType::f32);
    x.upload(xv.data(), xv.size());
    std::vector<std::int64_t> cam_lines = sc.image_shape();
    cam_lines.back() = 1;
    DeviceArray yc(ctx.device, cam_lines, DType::f32), yl(ctx.device, {std::int64_t(rays), 1},
                                                           DType::f32);
    yc.upload(yv.data(), yv.size());
    yl.upload(yv.data(), yv.size());
    for (const char* op : {"project", "backproject", "render"}) {
      // The camera's first, then the list's, held to the camera's: N and the render bit for bit
      // (the same rays, kernels/geometry.cl), Nᵀ to rounding (its atomics' order).
      const Check ok{true, "", "", 0, 0};
      Timed tc = time_op(ctx, sc, op, x, yc, ok);
      const bool exact = std::string(op) != "backproject";
      const std::vector<double> first = run_op(sl, op, x, yl).to_doubles();
      const Check check =
          exact ? check_max(difference(first, tc.first), "the camera's rays, bit for bit", 0, 0)
                : check_max(difference(first, tc.first), "the camera's rays (Nᵀ)", 1e-6, 1e-5);
      // Alternating rounds (camera, list, camera, …): a shared machine's drift hits both alike;
      // the ratio is the median of the rounds' ratios.
      Timed tl = time_op(ctx, sl, op, x, yl, check);
      std::vector<double> ratios{tc.m.wall.median / tl.m.wall.median};
      for (int round = 1; round < 3 && check.passed; ++round) {
        tc = time_op(ctx, sc, op, x, yc, ok);
        tl = time_op(ctx, sl, op, x, yl, check);
        ratios.push_back(tc.m.wall.median / tl.m.wall.median);
      }
      std::sort(ratios.begin(), ratios.end());
      const double ratio = ratios[ratios.size() / 2];
      Record rc{ctx.device_key, "rays", base + "_" + op, "ivr-camera-rays", params};
      add_timing(rc, tc.m);
      rc.metrics["rays_per_s"] = double(rays) / tc.m.wall.median;
      record_checked(ctx, std::move(rc), Check{true, "reference of the ray-list record", "", 0, 0});
      Record rl{ctx.device_key, "rays", base + "_" + op, "ivr-ray-list", params};
      add_timing(rl, tl.m);
      rl.metrics["rays_per_s"] = double(rays) / tl.m.wall.median;
      rl.metrics["throughput_vs_camera_rays"] = ratio;
      rl.metrics["rounds"] = double(ratios.size());
      std::cerr << "ivr-bench: rays/" << base << "_" << op << ": list "
                << tl.m.wall.median * 1e3 << " ms, camera rays " << tc.m.wall.median * 1e3
                << " ms (throughput " << ratio << "x, median of " << ratios.size()
                << " alternating rounds)\n";
      record_checked(ctx, std::move(rl), check);
    }
    // Sightlines ending inside: as many as the cameras' rays, from the centre.
    Scene stars = cameras;
    stars.cameras.clear();
    stars.rays = sightlines(rays, stars);
    Session ss(ctx.device, stars);
    DeviceArray ys(ctx.device, {std::int64_t(rays), 1}, DType::f32);
    ys.upload(yv.data(), yv.size());
    const double lhs = dot(ss.project(x).to_doubles(), yv),
                 rhs = dot(xv, ss.backproject(ys).to_doubles());
    const double mismatch = std::abs(lhs - rhs) / std::max(std::abs(lhs), std::abs(rhs));
    const Check dot_check{mismatch <= 1e-5, "⟨N x, y⟩ = ⟨x, Nᵀ y⟩", "relative", mismatch, 1e-5};
    for (const char* op : {"project", "backproject"}) {
      Timed t = time_op(ctx, ss, op, x, ys, dot_check);
      Record r{ctx.device_key, "rays", base + "_sightlines_" + op, "ivr-ray-list", params};
      add_timing(r, t.m);
      r.metrics["rays_per_s"] = double(rays) / t.m.wall.median;
      record_checked(ctx, std::move(r), dot_check);
    }
    // The gradient with respect to every sightline's origin, direction and ends (one forward
    // pass of 8 lanes) against the render of the same list, timed in the same run. Its check:
    // finite, and every direction's gradient tangent to the unit sphere.
    std::vector<float> target = ss.render().to_floats();
    for (float& v : target) v *= 0.9f;
    DeviceArray t_array(ctx.device, ss.image_shape(), DType::f32);
    t_array.upload(target.data(), target.size());
    ss.set_target(t_array);
    const std::vector<double> g = run_op(ss, "rays_gradient", x, ys).to_doubles();
    double largest = 0, worst_along = 0;
    bool finite = g.size() == rays * RayList::kColumns;
    for (double v : g) finite = finite && std::isfinite(v), largest = std::max(largest, std::abs(v));
    for (std::size_t r = 0; finite && r < rays; ++r) {
      const double* row = stars.rays.values.data() + r * RayList::kColumns;
      const double* gr = g.data() + r * RayList::kColumns;
      worst_along =
          std::max(worst_along, std::abs(row[3] * gr[3] + row[4] * gr[4] + row[5] * gr[5]));
    }
    const double along = largest > 0 ? worst_along / largest : 1;
    const Check grad_check{finite && along <= 1e-5, "finite; directions' gradients tangent",
                           "relative", along, 1e-5};
    const Timed render_t = time_op(ctx, ss, "render", x, ys, grad_check);
    const Timed grad_t = time_op(ctx, ss, "rays_gradient", x, ys, grad_check);
    Record r{ctx.device_key, "rays", base + "_sightlines_rays_gradient", "ivr-ray-list", params};
    add_timing(r, grad_t.m);
    r.metrics["rays_per_s"] = double(rays) / grad_t.m.wall.median;
    r.metrics["vs_render"] = grad_t.m.wall.median / render_t.m.wall.median;
    std::cerr << "ivr-bench: rays/" << base << "_sightlines_rays_gradient: "
              << grad_t.m.wall.median * 1e3 << " ms, render " << render_t.m.wall.median * 1e3
              << " ms (" << r.metrics["vs_render"].get<double>() << "x)\n";
    record_checked(ctx, std::move(r), grad_check);
  }
}

}  // namespace ivr::bench
