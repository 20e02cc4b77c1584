// planner.cpp — the planner suite, the crossover between the modes it chooses from: forward mode
// (P tangent lanes through one march) against the adjoint (one reverse pass, any number of
// parameters) for the TF and background parameters, by P; the measured crossover beside the
// device's cost model's; and forward mode against JAX's jacfwd, Dr.Jit's dr.forward and PyTorch's
// jvp on the 16 TF parameters. The adjoint is checked against central differences of the float64
// reference; the forward lanes against the adjoint.
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"
#include "reference/reference.hpp"

namespace ivr::bench {

namespace {

constexpr double kFdTolerance = 2e-3;  // relative, adjoint against central differences
constexpr double kLaneRtol = 1e-3;     // forward lanes against the adjoint, of its largest entry

double reference_loss(const Scene& scene, double step_world, const Image& target) {
  const std::vector<double> img = reference::render_midpoint(scene, step_world, true);
  double sum = 0;
  for (std::size_t i = 0; i < img.size(); ++i)
    sum += (img[i] - target.pixels[i]) * (img[i] - target.pixels[i]);
  return sum / double(img.size());
}

// The adjoint's value for a tf or background parameter (rows × 4 then the background).
double adjoint_value(const AdjointGradient& g, const Parameter& p) {
  if (p.group == ParameterGroup::background) return g.background[std::size_t(p.index)];
  return g.tf[std::size_t(p.index) * 4 + std::size_t(p.column)];
}

// P distinct voxels drawn with a fixed seed from the volume's middle half (where rays see them).
std::string voxel_list(const Scene& scene, int p) {
  const Volume& v = scene.volume;
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> x(v.nx / 4, 3 * v.nx / 4), y(v.ny / 4, 3 * v.ny / 4),
      z(v.nz / 4, 3 * v.nz / 4);
  std::vector<std::int64_t> picked;
  while (picked.size() < std::size_t(p)) {
    const std::int64_t i = (std::int64_t(z(rng)) * v.ny + y(rng)) * v.nx + x(rng);
    if (std::find(picked.begin(), picked.end(), i) == picked.end()) picked.push_back(i);
  }
  std::string list = "voxels:";
  for (std::size_t k = 0; k < picked.size(); ++k)
    list += (k ? "," : "") + std::to_string(picked[k]);
  return list;
}

// Voxel parameters by count P (powers of two up to 256; 16 --quick): forward mode ("ivr-forward"),
// the adjoint ("ivr-adjoint": every voxel at once, the same for every P) and the planner's
// automatic choice ("ivr"), with the automatic run's time over the faster mode's (issue 4's
// target: at most 1.25) and forward mode's in renders (at most 1 + P/2 up to P = 32). Checked
// before timing: forward mode's derivatives equal the adjoint's at the same voxels.
void voxel_sweep(Context& ctx) {
  const int n = ctx.quick ? 32 : 128, image = ctx.quick ? 64 : 256, max_p = ctx.quick ? 16 : 256;
  const Scene scene = bench_scene(n, image);
  const Image target = perturbed_target(ctx.device, scene, 0);
  GradientOptions forward, adjoint_mode, automatic;
  forward.mode = Mode::forward;
  adjoint_mode.mode = Mode::adjoint;
  const std::string base = "voxels_v" + std::to_string(n) + "_i" + std::to_string(image);
  RenderStats rs;
  const Measurement render_m = measure(ctx.budget, [&] {
    render(ctx.device, scene, {Precision::f32}, &rs);
    return rs.kernel_seconds;
  });
  const double render_s = render_m.device ? render_m.device->median : render_m.wall.median;
  const std::string one = voxel_list(scene, 1);
  Gradient a;
  const Measurement adjoint_m = measure(ctx.budget, [&] {
    a = gradient(ctx.device, scene, target, {one}, adjoint_mode);
    return a.kernel_seconds;
  });
  const double adjoint_s = adjoint_m.device ? adjoint_m.device->median : adjoint_m.wall.median;
  {
    Record r{ctx.device_key,
             "planner",
             base + "_adjoint",
             "ivr-adjoint",
             {{"volume", n}, {"image", image}, {"parameters", "every voxel"}}};
    add_timing(r, adjoint_m);
    r.metrics["adjoint_over_render"] = adjoint_s / render_s;
    r.metrics["render_s"] = render_s;
    ctx.results.add(std::move(r));
  }
  for (int p = 1; p <= max_p; p *= 2) {
    const std::string group = voxel_list(scene, p);
    const nlohmann::json params = {{"volume", n}, {"image", image}, {"parameters", p}};
    const std::vector<double> expected =
        gradient(ctx.device, scene, target, {group}, adjoint_mode).groups.at(0).values;
    Gradient f;
    Check check;
    const Measurement fm = measure(
        ctx.budget,
        [&] {
          f = gradient(ctx.device, scene, target, {group}, forward);
          return f.kernel_seconds;
        },
        [&] {
          check = check_max(difference(f.groups.at(0).values, expected), "ivr adjoint", 1e-12,
                            kLaneRtol);
          return check.passed;
        });
    const double forward_s = fm.device ? fm.device->median : fm.wall.median;
    Record rf{ctx.device_key, "planner", base + "_p" + std::to_string(p), "ivr-forward", params};
    add_timing(rf, fm);
    rf.metrics["forward_over_render"] = forward_s / render_s;
    if (p <= 32) rf.metrics["forward_limit_renders"] = 1 + 0.5 * p;
    record_checked(ctx, std::move(rf), check);
    Gradient g;
    const Measurement am = measure(ctx.budget, [&] {
      g = gradient(ctx.device, scene, target, {group}, automatic);
      return g.kernel_seconds;
    });
    const double auto_s = am.device ? am.device->median : am.wall.median;
    Record ra{ctx.device_key, "planner", base + "_p" + std::to_string(p), "ivr", params};
    add_timing(ra, am);
    ra.metrics["auto_over_faster"] = auto_s / std::min(forward_s, adjoint_s);
    ra.metrics["auto_chose_forward"] = g.plan.mode == Mode::forward ? 1 : 0;
    ra.metrics["predicted_forward_s"] = g.plan.forward_seconds;
    ra.metrics["predicted_adjoint_s"] = g.plan.adjoint_seconds;
    record_checked(ctx, std::move(ra), check);
  }
}

// TF and background parameters: the adjoint, forward mode by lane count, the crossover.
void tf_lanes(Context& ctx) {
  const int n = ctx.quick ? 32 : 64, image = ctx.quick ? 64 : 128;
  const double step = 0.5;
  const std::string case_base = "v" + std::to_string(n) + "_i" + std::to_string(image);
  const Scene scene = bench_scene(n, image);
  const Image target = perturbed_target(ctx.device, scene, step);
  std::vector<Parameter> pool = parameters_of(scene, "tf");
  for (const Parameter& p : parameters_of(scene, "background")) pool.push_back(p);
  nlohmann::json params = {{"volume", n}, {"image", image}, {"step", step}, {"loss", "mse"}};

  // The adjoint: every TF row and the background in one pass.
  AdjointOptions go;
  go.step = step;
  go.density = false;
  go.tf = go.background = true;
  AdjointGradient adj;
  Measurement am;
  {
    // Central differences of the reference loss for two parameters, a colour and an extinction,
    // against the adjoint, both without early termination: a ray whose transmittance crosses the
    // threshold between the two evaluations jumps by ~ the threshold, which swamps the quotient.
    Scene smooth = scene;
    smooth.integrator.min_transmittance = 0;
    const AdjointGradient smooth_adj = adjoint(ctx.device, smooth, target, go);
    const double hw = reference::min_voxel_edge(scene) * step, eps = 1e-4;
    double worst = 0;
    for (const auto& [row, column] : {std::pair{2, 0}, std::pair{2, 3}}) {
      Scene up = smooth, down = smooth;
      TfPoint &pu = up.tf.points[std::size_t(row)], &pd = down.tf.points[std::size_t(row)];
      const double scale = column == 3 ? pu.extinction : 1.0;
      if (column == 3) {
        pu.extinction += eps * scale;
        pd.extinction -= eps * scale;
      } else {
        pu.color[column] += eps;
        pd.color[column] -= eps;
      }
      const double fd =
          (reference_loss(up, hw, target) - reference_loss(down, hw, target)) / (2 * eps * scale);
      const double got = smooth_adj.tf[std::size_t(row) * 4 + std::size_t(column)];
      worst = std::max(worst, std::abs(got - fd) / std::max(std::abs(fd), 1e-30));
    }
    am = measure(
        ctx.budget,
        [&] {
          adj = adjoint(ctx.device, scene, target, go);
          return adj.kernel_seconds;
        },
        [&] { return worst <= kFdTolerance; });
    Record r{ctx.device_key, "planner", case_base + "_adjoint", "ivr-adjoint", params};
    r.params["parameters"] = pool.size();
    add_timing(r, am);
    r.metrics["peak_device_bytes"] = adj.device_bytes;
    r.metrics["memory_bytes"] = operation_memory(ctx, am, adj.device_bytes);
    Check k{worst <= kFdTolerance,
            "float64 reference, central differences (2 TF parameters, no early termination)",
            "relative", worst, kFdTolerance};
    record_checked(ctx, std::move(r), k);
  }
  double adjoint_ref_max = 0;
  for (const Parameter& p : pool)
    adjoint_ref_max = std::max(adjoint_ref_max, std::abs(adjoint_value(adj, p)));

  // Resident (the scene and target on the device in one session): the same adjoint, and forward
  // mode on any parameter list, each held to the one-shot adjoint checked above.
  SessionOptions so;
  so.step = step;
  Session session(ctx.device, scene, so);
  session.set_target(target);
  // Times `run` (it enqueues; the clock stops once the derivatives are ready on the device),
  // checked against `expected` — the one-shot adjoint's values, checked above — first.
  auto record_resident = [&](const std::string& case_name, const std::string& implementation,
                             const nlohmann::json& record_params,
                             const std::function<SessionGradient()>& run,
                             const std::vector<double>& expected) {
    SessionGradient g;
    double worst = INFINITY;
    const Measurement m = measure_resident(
        ctx.budget, session,
        [&] {
          g = run();
          g.groups.back().second.wait();
          g.loss.wait();
        },
        [&] {
          std::vector<double> values;
          for (const auto& group : g.groups) {
            const std::vector<double> v = group.second.to_doubles();
            values.insert(values.end(), v.begin(), v.end());
          }
          worst = values.size() == expected.size() ? 0.0 : INFINITY;
          for (std::size_t i = 0; i < values.size() && i < expected.size(); ++i)
            worst = std::max(worst, std::abs(values[i] - expected[i]));
          return worst <= kLaneRtol * adjoint_ref_max;
        });
    const OperationStats stats = session.last_stats();
    Record r{ctx.device_key, "planner", case_name, implementation, record_params};
    add_timing(r, m);
    r.metrics["peak_device_bytes"] = stats.device_bytes;
    r.metrics["memory_bytes"] = operation_memory(ctx, m, stats.device_bytes);
    Check k{worst <= kLaneRtol * adjoint_ref_max, "ivr one-shot adjoint (checked above)", "max_abs",
            worst, kLaneRtol * adjoint_ref_max};
    record_checked(ctx, std::move(r), k);
  };
  {
    GradientRequest request;
    request.wrt = {"tf", "background"};
    request.mode = Mode::adjoint;
    std::vector<double> expected = adj.tf;
    expected.insert(expected.end(), adj.background.begin(), adj.background.end());
    nlohmann::json p = params;
    p["parameters"] = pool.size();
    record_resident(
        case_base + "_adjoint", "ivr-resident", p, [&] { return session.gradient(request); },
        expected);
  }

  // Forward mode by lane count.
  std::vector<int> lanes =
      ctx.quick ? std::vector<int>{1, 4, 16} : std::vector<int>{1, 2, 4, 8, 16, 32};
  std::vector<std::pair<double, double>> curve;  // (lanes, median seconds)
  std::vector<float> tf16;                       // the 16 TF lanes' gradient
  for (int P : lanes) {
    std::vector<Parameter> ps;
    for (int i = 0; i < P; ++i) ps.push_back(pool[std::size_t(i) % pool.size()]);
    JacobianOptions to;
    to.step = step;
    Jacobian t;
    double worst = 0;
    const Measurement m = measure(
        ctx.budget,
        [&] {
          t = jacobian(ctx.device, scene, ps, &target, to);
          return t.kernel_seconds;
        },
        [&] {
          for (int i = 0; i < P; ++i)
            worst = std::max(worst, std::abs(t.gradient[std::size_t(i)] -
                                             adjoint_value(adj, ps[std::size_t(i)])));
          return worst <= kLaneRtol * adjoint_ref_max;
        });
    Record r{ctx.device_key, "planner", case_base + "_lanes_" + std::to_string(P), "ivr-forward",
             params};
    r.params["lanes"] = P;
    add_timing(r, m);
    r.metrics["ratio_to_adjoint"] = m.wall.median / am.wall.median;
    r.metrics["peak_device_bytes"] = t.device_bytes;
    r.metrics["memory_bytes"] = operation_memory(ctx, m, t.device_bytes);
    Check k{worst <= kLaneRtol * adjoint_ref_max, "ivr adjoint (checked above)", "max_abs", worst,
            kLaneRtol * adjoint_ref_max};
    const bool passed = k.passed;
    record_checked(ctx, std::move(r), k);
    if (passed) curve.push_back({double(P), m.wall.median});
    std::vector<double> expected;
    for (const Parameter& p : ps) expected.push_back(adjoint_value(adj, p));
    nlohmann::json p = params;
    p["lanes"] = P;
    record_resident(
        case_base + "_lanes_" + std::to_string(P), "ivr-resident", p,
        [&] { return session.forward(ps); }, expected);
  }

  // The measured crossover: where forward mode's time (linear in P between measured points)
  // reaches the adjoint's; the cost model's prediction beside it.
  {
    Record r{ctx.device_key, "planner", case_base + "_summary", "ivr", params};
    double crossover = INFINITY;
    for (std::size_t i = 0; i < curve.size(); ++i) {
      if (curve[i].second < am.wall.median) continue;
      if (i == 0) {
        crossover = curve[0].first;
      } else {
        const auto [p0, t0] = curve[i - 1];
        const auto [p1, t1] = curve[i];
        crossover = p0 + (am.wall.median - t0) * (p1 - p0) / (t1 - t0);
      }
      break;
    }
    r.metrics["crossover_lanes"] = std::isfinite(crossover) ? crossover : -1.0;
    const CostModel model = load_cost_model(ctx.device.info());
    double predicted = -1;
    for (int P = 1; P <= 64; ++P)
      if (forward_cost(model, std::size_t(P)) >= model.adjoint) {
        predicted = P;
        break;
      }
    r.metrics["model_crossover_lanes"] = predicted;
    r.params["cost_model"] = model.source;
    r.note = std::isfinite(crossover)
                 ? ""
                 : "forward mode stayed faster than the adjoint up to the largest P measured";
    ctx.results.add(std::move(r));
  }

  // Forward mode on the 16 TF parameters against the Python baselines' forward mode.
  std::vector<Parameter> tf_params = parameters_of(scene, "tf");
  JacobianOptions to;
  to.step = step;
  Jacobian t;
  const std::vector<double> adjoint_tf(adj.tf.begin(), adj.tf.end());
  Check check;
  const Measurement m = measure(
      ctx.budget,
      [&] {
        t = jacobian(ctx.device, scene, tf_params, &target, to);
        return t.kernel_seconds;
      },
      [&] {
        check = check_max(difference(t.gradient, adjoint_tf), "ivr adjoint", 0, kLaneRtol);
        return check.passed;
      });
  const std::string name = case_base + "_tf" + std::to_string(tf_params.size());
  params["lanes"] = tf_params.size();
  {
    Record r{ctx.device_key, "planner", name, "ivr", params};
    add_timing(r, m);
    r.metrics["memory_bytes"] = operation_memory(ctx, m, t.device_bytes);
    record_checked(ctx, std::move(r), check);
  }
  record_resident(
      name, "ivr-resident", params, [&] { return session.forward(tf_params); }, adjoint_tf);
  if (!ctx.python_baselines) return;
  const std::string dir = write_case(ctx.work_dir + "/planner_" + name, scene, step, target);
  run_python_baselines(ctx, "planner", name, params, dir, "tf_forward", "tf_grad",
                       [&](const BaselineRun& run, Record&) {
                         return check_max(difference(run.output, adjoint_tf),
                                          "ivr adjoint (checked against the reference)", 0,
                                          kLaneRtol);
                       });
}

}  // namespace

void planner_suite(Context& ctx) {
  tf_lanes(ctx);
  voxel_sweep(ctx);
}

}  // namespace ivr::bench
