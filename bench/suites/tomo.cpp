// tomo.cpp — the tomography suite: throughput of the linear absorption projector and its transpose
// (parallel and cone beam). Checked before timing: the projection of σ = 1 against each ray's
// chord through the box (closed form), and the dot-product test ⟨N x, y⟩ = ⟨x, Nᵀ y⟩.
#include <cmath>
#include <random>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

namespace {

// Each ray's chord through the box (the exact line integral of σ = 1): the orthographic rays of
// the tomography scene, clipped in double precision.
std::vector<double> chords(const Scene& scene) {
  std::vector<double> out;
  for (const Camera& c : scene.cameras) {
    const glm::dvec3 fwd = glm::normalize(c.target - c.eye),
                     right = glm::normalize(glm::cross(fwd, c.up)), up = glm::cross(right, fwd);
    const double half_h = 0.5 * c.ortho_height, half_w = half_h * c.width / c.height;
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        const double sx = 2.0 * (x + 0.5) / c.width - 1, sy = 1 - 2.0 * (y + 0.5) / c.height;
        const glm::dvec3 o = c.eye + sx * half_w * right + sy * half_h * up;
        double t0 = -INFINITY, t1 = INFINITY;
        for (int a = 0; a < 3; ++a) {
          if (fwd[a] == 0) {
            if (o[a] < scene.box_min[a] || o[a] > scene.box_max[a]) t1 = -INFINITY;
            continue;
          }
          const double ta = (scene.box_min[a] - o[a]) / fwd[a],
                       tb = (scene.box_max[a] - o[a]) / fwd[a];
          t0 = std::max(t0, std::min(ta, tb));
          t1 = std::min(t1, std::max(ta, tb));
        }
        out.push_back(std::max(0.0, t1 - t0));
      }
  }
  return out;
}

}  // namespace

void tomo_suite(Context& ctx) {
  const std::vector<int> sizes = ctx.quick ? std::vector<int>{32} : std::vector<int>{64, 128};
  for (int n : sizes)
    for (bool cone : {false, true}) {
      const int views = n / 2;
      const Scene scene = tomo_scene(n, views, cone, 1);
      const Projector P(ctx.device, scene);
      const std::vector<double> x = uniform(P.voxel_count(), 1), y = uniform(P.ray_count(), 2);
      const double lhs = dot(P.project(x), y), rhs = dot(x, P.backproject(y));
      const double mismatch = std::abs(lhs - rhs) / std::max(std::abs(lhs), std::abs(rhs));
      Check check{mismatch <= 1e-5, "⟨N x, y⟩ = ⟨x, Nᵀ y⟩", "relative", mismatch, 1e-5};
      if (!cone && check.passed) {  // the chords: parallel beam has them in closed form
        const Check chord = check_max(
            difference(P.project(std::vector<double>(P.voxel_count(), 1.0)), chords(scene)),
            "chord lengths through the box (closed form)", 1e-6, 1e-5);
        if (!chord.passed) check = chord;
      }
      const std::string base = "v" + std::to_string(n) + "_" + (cone ? "cone" : "parallel");
      const nlohmann::json params = {{"volume", n},
                                     {"views", views},
                                     {"detector", n},
                                     {"beam", cone ? "cone" : "parallel"},
                                     {"rays", P.ray_count()}};
      for (bool transpose : {false, true}) {
        const Measurement m = measure(
            ctx.budget,
            [&] {
              if (transpose)
                P.backproject(y);
              else
                P.project(x);
              return P.last_kernel_seconds();
            },
            [&] { return check.passed; });
        Record r{ctx.device_key, "tomo", base + (transpose ? "_backproject" : "_project"), "ivr",
                 params};
        add_timing(r, m);
        r.metrics["rays_per_s"] = double(P.ray_count()) / m.wall.median;
        r.metrics["ray_cells_per_s"] = double(P.ray_count()) * n / m.wall.median;
        r.metrics["memory_bytes"] = operation_memory(ctx, m, 0);
        record_checked(ctx, std::move(r), check);
      }
      // Resident: the volume and the lines already on the device, the result left there; held
      // to the same dot-product test on device arrays first.
      Scene geometry = scene;
      geometry.volume.data.clear();
      Session session(ctx.device, geometry);
      DeviceArray xd(ctx.device, session.volume_shape(), DType::f32);
      std::vector<std::int64_t> ray_shape = session.image_shape();
      ray_shape[3] = 1;
      DeviceArray yd(ctx.device, ray_shape, DType::f32);
      xd.upload(x.data(), x.size());
      yd.upload(y.data(), y.size());
      const double resident_lhs = dot(session.project(xd).to_doubles(), y),
                   resident_rhs = dot(x, session.backproject(yd).to_doubles());
      const double resident_mismatch = std::abs(resident_lhs - resident_rhs) /
                                       std::max(std::abs(resident_lhs), std::abs(resident_rhs));
      const Check resident_check{resident_mismatch <= 1e-5 && check.passed,
                                 "⟨N x, y⟩ = ⟨x, Nᵀ y⟩ on device arrays", "relative",
                                 resident_mismatch, 1e-5};
      for (bool transpose : {false, true}) {
        DeviceArray out;
        const Measurement m = measure_resident(
            ctx.budget, session,
            [&] {
              out = transpose ? session.backproject(yd) : session.project(xd);
              out.wait();
            },
            [&] { return resident_check.passed; });
        Record r{ctx.device_key, "tomo", base + (transpose ? "_backproject" : "_project"),
                 "ivr-resident", params};
        add_timing(r, m);
        r.metrics["rays_per_s"] = double(P.ray_count()) / m.wall.median;
        r.metrics["ray_cells_per_s"] = double(P.ray_count()) * n / m.wall.median;
        r.metrics["memory_bytes"] = operation_memory(ctx, m, 0);
        record_checked(ctx, std::move(r), resident_check);
      }
    }
}

}  // namespace ivr::bench
