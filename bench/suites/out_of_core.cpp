// out_of_core.cpp — the out-of-core suite (docs/scaling.md): the render, the density gradient
// (float sums and fixed point) and forward mode of a volume streamed through the device in bricks (midpoint; trapezoid at 64³)
// against the same operation in core, end to end, in alternating rounds (issue 24's target:
// bricked ≥ 0.7× the in-core throughput where the volume fits); the volume's slabs over two
// devices of one process against one in core; and, with --cases v1024, a 1024³ volume under a
// 1 GiB device-memory cap beside the in-core 512³ scaled by volume.
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <optional>

#include "ivr/domain.hpp"

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

namespace {

double seconds_of(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// One way against in core, in alternating rounds (3, while `check` holds): the last round's
// measurements and the median over the rounds of the in-core / other wall-time ratio.
struct Alternated {
  Measurement in_core, other;
  double ratio = 0;
};
Alternated alternate(Context& ctx, const Check& check, const std::function<void()>& in_core,
                     const std::function<void()>& other) {
  Alternated a;
  std::vector<double> ratios;
  for (int round = 0; round < 3 && check.passed; ++round) {
    a.in_core = measure(ctx.budget, [&] { in_core(); return -1.0; });
    a.other = measure(ctx.budget, [&] { other(); return -1.0; });
    ratios.push_back(a.in_core.wall.median / a.other.wall.median);
  }
  std::sort(ratios.begin(), ratios.end());
  a.ratio = ratios.empty() ? 0 : ratios[ratios.size() / 2];
  return a;
}

// Procedural densities of an n³ grid (x fastest), for large n (no file).
template <typename T>
std::vector<T> procedural_volume(int n) {
  std::vector<T> values(std::size_t(n) * n * n);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const double u = (x + 0.5) / n - 0.5, v = (y + 0.5) / n - 0.5, w = (z + 0.5) / n - 0.5;
        values[(std::size_t(z) * n + y) * n + x] =
            T(std::exp(-(u * u + v * v + w * w) / 0.08) * (1 + 0.3 * std::sin(20 * u)));
      }
  return values;
}

// The benchmark scene with the procedural densities.
Scene large_scene(int n, int image) {
  Scene s = bench_scene(32, image);
  s.volume.nx = s.volume.ny = s.volume.nz = n;
  s.volume.data = procedural_volume<float>(n);
  return s;
}

// In core against bricks of `edge` cells: the render, the density gradient (adjoint) and forward
// mode (the TF's and the cameras' lanes, and the TF's alone); the ratio is the median over alternating rounds of
// in-core / bricked wall time.
void compare(Context& ctx, const std::string& base, const Scene& scene, int edge) {
  const nlohmann::json params = {{"volume", scene.volume.nx}, {"image", scene.cameras[0].width},
                                 {"brick_edge", edge}};
  RenderOptions in_core, bricked;
  bricked.volume_brick = edge;
  RenderStats st;
  const Image a = render(ctx.device, scene, in_core), b = render(ctx.device, scene, bricked, &st);
  const Check image_check =
      check_max(difference(b.pixels, widen(a.pixels)), "the in-core render", 1e-6, 1e-5);
  Image target = a;
  for (float& v : target.pixels) v = 0.9f * v + 0.02f;
  // The gradients: each group's values one after another.
  struct GradientOp {
    const char* name;
    std::vector<std::string> groups;
    Mode mode;
    bool deterministic;  // the density in fixed point (in core and out of core alike)
  };
  auto run_gradient = [&](const GradientOp& g, bool in_bricks) {
    GradientOptions go;
    go.mode = g.mode;
    go.deterministic = g.deterministic;
    std::optional<ScopedEnv> force;
    if (in_bricks) force.emplace("IVR_VOLUME_BRICK", std::to_string(edge));
    std::vector<double> all;
    for (const GroupGradient& group : gradient(ctx.device, scene, target, g.groups, go).groups)
      all.insert(all.end(), group.values.begin(), group.values.end());
    return all;
  };
  const std::vector<GradientOp> gradients = {
      {"gradient", {"density"}, Mode::adjoint, false},
      {"gradient_fixed", {"density"}, Mode::adjoint, true},
      {"forward", {"tf", "camera"}, Mode::forward, false},
      // The TF's lanes alone: in core they march packets of rays on CPUs (camera lanes do not).
      {"forward_tf", {"tf"}, Mode::forward, false}};
  std::vector<Check> checks = {image_check};
  for (const GradientOp& g : gradients)
    checks.push_back(check_max(difference(run_gradient(g, true), run_gradient(g, false)),
                               std::string("the in-core ") + (g.mode == Mode::forward
                                                                  ? "forward mode"
                                                                  : "adjoint"),
                               0, 1e-5));
  for (std::size_t op = 0; op < 1 + gradients.size(); ++op) {
    const bool is_render = op == 0;
    auto run_in_core = [&] {
      if (is_render) (void)render(ctx.device, scene, in_core);
      else (void)run_gradient(gradients[op - 1], false);
    };
    auto run_bricked = [&] {
      if (is_render) (void)render(ctx.device, scene, bricked);
      else (void)run_gradient(gradients[op - 1], true);
    };
    const Check& check = checks[op];
    const Alternated t = alternate(ctx, check, run_in_core, run_bricked);
    const Measurement &mi = t.in_core, &mb = t.other;
    const double ratio = t.ratio;
    const std::string name = base + "_" + (is_render ? "render" : gradients[op - 1].name);
    Record ri{ctx.device_key, "out_of_core", name, "ivr-in-core", params};
    add_timing(ri, mi);
    record_checked(ctx, std::move(ri), Check{true, "reference of the bricked record", "", 0, 0});
    Record rb{ctx.device_key, "out_of_core", name, "ivr-bricked", params};
    add_timing(rb, mb);
    rb.metrics["throughput_vs_in_core"] = ratio;
    rb.metrics["bricks"] = double(st.bricks);
    std::cerr << "ivr-bench: out_of_core/" << name << ": bricked (" << st.bricks << " bricks of "
              << edge << ") " << mb.wall.median * 1e3 << " ms, in core " << mi.wall.median * 1e3
              << " ms (throughput " << ratio << "x)\n";
    record_checked(ctx, std::move(rb), check);
  }
}

// The volume's slabs over two devices of one process (render_domain / gradient_domain over
// devices; here two contexts on the bench device, which share its compute units — what two GPUs
// would run) against the device in core: the render over states and over segments and the density
// gradient, each checked against the in-core result; the ratio is the in-core / slabs wall time.
void device_slabs(Context& ctx, const std::string& name, Scene scene) {
  scene.integrator.min_transmittance = 0;  // (segments: one process's march)
  Device second(std::to_string(ctx.device.info().index));
  const std::vector<Device*> devices = {&ctx.device, &second};
  const nlohmann::json params = {{"volume", scene.volume.nx}, {"image", scene.cameras[0].width},
                                 {"devices", 2}};
  const Image in_core = render(ctx.device, scene);
  Image target = in_core;
  for (float& v : target.pixels) v = 0.9f * v + 0.02f;
  GradientOptions go;
  go.mode = Mode::adjoint;
  struct Op {
    const char* name;
    std::function<std::vector<double>()> one, slabs;
  };
  auto pixels = [](const Image& i) { return widen(i.pixels); };
  auto density = [](const Gradient& g) { return g.groups[0].values; };
  const std::vector<Op> ops = {
      {"render", [&] { return pixels(render(ctx.device, scene)); },
       [&] { return pixels(render_domain(devices, scene, SlabMarch::states)); }},
      {"render_segments", [&] { return pixels(render(ctx.device, scene)); },
       [&] { return pixels(render_domain(devices, scene, SlabMarch::segments)); }},
      {"gradient", [&] { return density(gradient(ctx.device, scene, target, {"density"}, go)); },
       [&] {
         return density(gradient_domain(devices, scene, target, SlabMarch::states, go));
       }}};
  for (const Op& op : ops) {
    const Check check =
        check_max(difference(op.slabs(), op.one()), "one device in core", 0, 1e-5);
    const Alternated t =
        alternate(ctx, check, [&] { (void)op.one(); }, [&] { (void)op.slabs(); });
    const Measurement &mi = t.in_core, &ms = t.other;
    const double ratio = t.ratio;
    const std::string case_name = name + "_" + op.name;
    Record ri{ctx.device_key, "out_of_core", case_name, "ivr-in-core", params};
    add_timing(ri, mi);
    record_checked(ctx, std::move(ri), Check{true, "reference of the slabs record", "", 0, 0});
    Record rs{ctx.device_key, "out_of_core", case_name, "ivr-2-device-slabs", params};
    add_timing(rs, ms);
    rs.metrics["throughput_vs_in_core"] = ratio;
    std::cerr << "ivr-bench: out_of_core/" << case_name << ": 2 devices' slabs "
              << ms.wall.median * 1e3 << " ms, one device in core " << mi.wall.median * 1e3
              << " ms (throughput " << ratio << "x)\n";
    record_checked(ctx, std::move(rs), check);
  }
}

// A 1024³ volume under a 1 GiB cap (render and density gradient, once each: they take minutes
// here), beside the in-core 512³ (scaled by 8, the voxels' ratio).
void capped(Context& ctx) {
  std::cerr << "ivr-bench: out_of_core/v1024_capped...\n";
  for (int n : {512, 1024}) {
    const Scene scene = large_scene(n, 256);
    std::optional<ScopedEnv> cap;
    if (n == 1024) cap.emplace("IVR_DEVICE_MEMORY_LIMIT", "1G");
    RenderStats st;
    reset_peak_resident();
    const std::uint64_t before = resident_bytes();
    Image image;
    const double render_s = seconds_of([&] { image = render(ctx.device, scene, {}, &st); });
    for (float& v : image.pixels) v = 0.9f * v + 0.02f;
    GradientOptions go;
    go.mode = Mode::adjoint;
    Gradient g;
    const double grad_s =
        seconds_of([&] { g = gradient(ctx.device, scene, image, {"density"}, go); });
    double largest = 0;
    bool finite = true;
    for (double v : g.groups[0].values) finite = finite && std::isfinite(v), largest = std::max(largest, std::abs(v));
    const Check check{finite && largest > 0, "finite, non-zero gradient", "", 0, 0};
    Record r{ctx.device_key, "out_of_core", "v" + std::to_string(n) + "_capped",
             n == 1024 ? "ivr-bricked-1GiB" : "ivr-in-core",
             {{"volume", n}, {"image", 256}, {"cap_bytes", n == 1024 ? (1ull << 30) : 0ull}}};
    r.metrics["render_s"] = render_s;
    r.metrics["render_kernel_s"] = st.kernel_seconds;
    r.metrics["gradient_s"] = grad_s;
    r.metrics["gradient_kernel_s"] = g.kernel_seconds;
    r.metrics["bricks"] = double(st.bricks);
    r.metrics["device_bytes_render"] = double(st.device_bytes);
    r.metrics["device_bytes_gradient"] = double(g.device_bytes);
    r.metrics["host_peak_bytes"] = double(peak_resident_bytes());
    r.metrics["host_before_bytes"] = double(before);
    std::cerr << "ivr-bench: out_of_core/v" << n << ": render " << render_s << " s (kernels "
              << st.kernel_seconds << " s, " << st.bricks << " bricks, device "
              << st.device_bytes / 1048576.0 << " MiB), gradient " << grad_s << " s (kernels "
              << g.kernel_seconds << " s, device " << g.device_bytes / 1048576.0
              << " MiB), host peak " << peak_resident_bytes() / 1048576.0 << " MiB\n";
    record_checked(ctx, std::move(r), check);
  }
}

// A few CGLS iterations of a 1024³ reconstruction under a 1 GiB cap (float32: the projector in
// bricks, three float32 volumes on the host), beside the in-core 512³ scaled by 8. The projections
// are N of the procedural volume; the record checks that the residual falls.
void capped_tomo(Context& ctx) {
  std::cerr << "ivr-bench: out_of_core/v1024_tomo...\n";
  constexpr int kIterations = 3, kViews = 8, kImage = 256;
  for (int n : {512, 1024}) {
    Scene scene;
    scene.volume.nx = scene.volume.ny = scene.volume.nz = n;
    set_default_box(scene);
    scene.model = Model::absorption;
    for (int v = 0; v < kViews; ++v) {
      const double a = 3.14159265358979323846 * v / kViews;
      Camera c;
      c.projection = Projection::orthographic;
      c.eye = {2 * std::sin(a), 0.3, 2 * std::cos(a)};
      c.ortho_height = 1.2, c.width = c.height = kImage;
      scene.cameras.push_back(c);
    }
    std::optional<ScopedEnv> cap;
    if (n == 1024) cap.emplace("IVR_DEVICE_MEMORY_LIMIT", "1G");
    reset_peak_resident();
    std::vector<double> lines;
    const double project_s = seconds_of([&] {
      const Projector N(ctx.device, scene, Precision::f32);
      lines = N.project(procedural_volume<double>(n));
    });
    TomoOptions o;
    o.iterations = kIterations;
    o.precision = Precision::f32;
    o.nonneg = true;
    TomoResult result;
    const double tomo_s = seconds_of([&] { result = tomo(ctx.device, scene, lines, o); });
    const bool falls = result.history.size() == std::size_t(kIterations) &&
                       result.history.back().residual < 0.5 * result.history.front().residual;
    const Check check{falls, "the residual halves in " + std::to_string(kIterations) + " iterations",
                      "", 0, 0};
    Record r{ctx.device_key, "out_of_core", "v" + std::to_string(n) + "_tomo",
             n == 1024 ? "ivr-bricked-1GiB" : "ivr-in-core",
             {{"volume", n}, {"views", kViews}, {"image", kImage}, {"iterations", kIterations},
              {"cap_bytes", n == 1024 ? (1ull << 30) : 0ull}}};
    r.metrics["tomo_s"] = tomo_s;
    r.metrics["iteration_s"] = tomo_s / kIterations;
    r.metrics["projections_s"] = project_s;
    r.metrics["bricks"] = double(result.bricks);
    r.metrics["residual_first"] = result.history.empty() ? 0 : result.history.front().residual;
    r.metrics["residual_last"] = result.history.empty() ? 0 : result.history.back().residual;
    r.metrics["host_peak_bytes"] = double(peak_resident_bytes());
    std::cerr << "ivr-bench: out_of_core/v" << n << "_tomo: " << kIterations << " CGLS iterations "
              << tomo_s << " s (" << result.bricks << " bricks), residual "
              << r.metrics["residual_first"] << " -> " << r.metrics["residual_last"]
              << ", host peak " << peak_resident_bytes() / 1048576.0 << " MiB\n";
    record_checked(ctx, std::move(r), check);
  }
}

}  // namespace

void out_of_core_suite(Context& ctx) {
  const std::vector<int> sizes = ctx.quick ? std::vector<int>{32} : std::vector<int>{64, 128};
  for (int n : sizes) {
    const std::string base = "v" + std::to_string(n) + "_i256";
    if (!ctx.wants(base)) continue;
    std::cerr << "ivr-bench: out_of_core/" << base << "...\n";
    const Scene scene = bench_scene(n, ctx.quick ? 64 : 256);
    compare(ctx, base + "_b" + std::to_string(n / 2), scene, n / 2);
  }
  // Many small bricks (64 of 8 cells, 32³ → 64²): each brick's march is short, so the per-brick
  // work of the host and the queue shows — the regime a GPU's bricks are in at every size.
  if (ctx.wants("v32_i64_many_bricks")) {
    std::cerr << "ivr-bench: out_of_core/v32_i64_many_bricks...\n";
    compare(ctx, "v32_i64_many_bricks_b8", bench_scene(32, 64), 8);
  }
  // The trapezoid scheme: its gradients' bricks hold a halo of ⌈step⌉ + 1 voxels (brick_halo).
  {
    const int n = ctx.quick ? 32 : 64;
    const std::string base = "v" + std::to_string(n) + "_i256_trapezoid";
    if (ctx.wants(base)) {
      std::cerr << "ivr-bench: out_of_core/" << base << "...\n";
      Scene scene = bench_scene(n, ctx.quick ? 64 : 256);
      scene.integrator.scheme = Scheme::trapezoid;
      compare(ctx, base + "_b" + std::to_string(n / 2), scene, n / 2);
    }
  }
  // Two devices' slabs (two contexts on this device here).
  {
    const int n = ctx.quick ? 32 : 64;
    const std::string base = "v" + std::to_string(n) + "_i256_device_slabs";
    if (ctx.wants(base)) {
      std::cerr << "ivr-bench: out_of_core/" << base << "...\n";
      device_slabs(ctx, base, bench_scene(n, ctx.quick ? 64 : 256));
    }
  }
  // Minutes and ~14 GB of host memory: only when asked for by name.
  if (std::find(ctx.cases.begin(), ctx.cases.end(), "v1024") != ctx.cases.end()) capped(ctx);
  if (std::find(ctx.cases.begin(), ctx.cases.end(), "v1024_tomo") != ctx.cases.end())
    capped_tomo(ctx);
}

}  // namespace ivr::bench
