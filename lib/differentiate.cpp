// differentiate.cpp — gradients by named group: the parameters each group stands for, the
// planner's choice of mode, and the run in that mode (lib/tangents.cpp or lib/adjoint.cpp).
#include "ivr/differentiate.hpp"

#include <algorithm>
#include <cctype>
#include <set>
#include <sstream>

#include "ivr/error.hpp"
#include "ivr/tangents.hpp"
#include "ivr/tolerance.hpp"

namespace ivr {

namespace {

Error bad_group(const std::string& what) {
  return Error(Status::invalid_argument, "--wrt: " + what);
}

bool is_index_item(const std::string& s) {
  const auto digits = [](const std::string& t) {
    return !t.empty() && std::all_of(t.begin(), t.end(), [](char c) { return std::isdigit(c); });
  };
  const std::size_t dash = s.find('-');
  return dash == std::string::npos ? digits(s)
                                   : digits(s.substr(0, dash)) && digits(s.substr(dash + 1));
}

// What one group needs: its forward-mode parameters, its output shape, and whether the adjoint
// computes it.
struct GroupPlan {
  std::string name;
  std::vector<Parameter> parameters;
  std::vector<std::size_t> shape;
  bool adjoint = true;
};

GroupPlan plan_group(const Scene& scene, const std::string& g) {
  static const std::set<std::string> known = {"density",    "tf",     "tf_points", "scales",
                                              "background", "camera", "step"};
  const bool voxels = g.rfind("voxels:", 0) == 0;
  if (!voxels && !known.count(g))
    throw bad_group("unknown parameter group '" + g +
                    "' (known: density, tf, tf_points, scales, background, camera, step, "
                    "voxels:LIST)");
  GroupPlan p;
  p.name = voxels ? "voxels" : g;
  p.parameters = parameters_of(scene, g);
  if (g == "density")
    p.shape = {std::size_t(scene.volume.nz), std::size_t(scene.volume.ny),
               std::size_t(scene.volume.nx)};
  else if (g == "tf")
    p.shape = tf_gradient_shape(scene.tf);
  else if (g == "camera")
    p.shape = {scene.cameras.size(), 7};
  else
    p.shape = {p.parameters.size()};
  p.adjoint = g != "tf_points";
  return p;
}

}  // namespace

std::vector<std::string> parse_groups(const std::string& list) {
  std::vector<std::string> groups;
  std::stringstream in(list);
  std::string item;
  bool in_voxels = false;
  std::set<std::string> seen;
  while (std::getline(in, item, ',')) {
    if (item.empty()) throw bad_group("empty group in '" + list + "'");
    if (in_voxels && is_index_item(item)) {
      groups.back() += "," + item;
      continue;
    }
    in_voxels = item.rfind("voxels:", 0) == 0;
    if (in_voxels && !is_index_item(item.substr(7)))
      throw bad_group("'" + item + "': voxels:LIST takes indices and ranges a-b");
    const std::string key = in_voxels ? "voxels" : item;
    if (!seen.insert(key).second) {
      if (in_voxels) throw bad_group("voxels:LIST given twice (give one list)");
      continue;  // a group named twice is computed once
    }
    groups.push_back(item);
  }
  if (groups.empty() || list.back() == ',') throw bad_group("empty group in '" + list + "'");
  return groups;
}

Differentiation differentiate(Device& device, const Scene& scene, const Image& target,
                              const std::vector<std::string>& groups,
                              const DifferentiateOptions& o) {
  std::vector<GroupPlan> plans;
  std::size_t forward_parameters = 0;
  bool adjoint_possible = true;
  for (const std::string& g : groups) {
    plans.push_back(plan_group(scene, g));
    forward_parameters += plans.back().parameters.size();
    adjoint_possible = adjoint_possible && plans.back().adjoint;
  }
  if (plans.empty()) throw bad_group("no group asked for");
  // The step once for both the plan and the mode that runs (a tolerance is estimated here).
  const double step =
      integrator_for(device, scene, o.step, o.precision, EmptySpace::automatic).step;
  Differentiation d;
  d.step = step;
  d.plan = plan_gradient(load_cost_model(device.info()), scene, forward_parameters, true,
                         adjoint_possible, o.mode, step);
  d.parameters = forward_parameters;

  if (d.plan.mode == Mode::forward) {
    std::vector<Parameter> all;
    for (const GroupPlan& p : plans)
      all.insert(all.end(), p.parameters.begin(), p.parameters.end());
    TangentOptions to;
    to.precision = o.precision;
    to.step = step;
    to.loss = o.loss;
    const Tangents t = tangents(device, scene, all, &target, to);
    d.loss = t.loss;
    d.kernel_seconds = t.kernel_seconds;
    d.device_bytes = t.device_bytes;
    std::size_t at = 0;
    for (const GroupPlan& p : plans) {
      d.groups.push_back(
          {p.name, p.shape,
           std::vector<double>(t.gradient.begin() + std::ptrdiff_t(at),
                               t.gradient.begin() + std::ptrdiff_t(at + p.parameters.size()))});
      at += p.parameters.size();
    }
    return d;
  }

  GradientOptions go;
  go.precision = o.precision;
  go.step = step;
  go.loss = o.loss;
  go.density = go.tf = go.background = false;
  for (const GroupPlan& p : plans) {
    go.density = go.density || p.name == "density" || p.name == "voxels";
    go.tf = go.tf || p.name == "tf" || p.name == "scales";
    go.background = go.background || p.name == "background";
    go.camera = go.camera || p.name == "camera";
  }
  const Gradient g = gradient(device, scene, target, go);
  d.loss = g.loss;
  d.kernel_seconds = g.kernel_seconds;
  d.device_bytes = g.device_bytes;
  d.atomics = g.atomics;
  for (const GroupPlan& p : plans) {
    GroupGradient out{p.name, p.shape, {}};
    if (p.name == "density")
      out.values.assign(g.density.begin(), g.density.end());
    else if (p.name == "voxels")
      for (const Parameter& q : p.parameters) out.values.push_back(g.density[std::size_t(q.index)]);
    else if (p.name == "tf" || p.name == "scales")
      out.values = g.tf;
    else if (p.name == "background")
      out.values = g.background;
    else if (p.name == "camera")
      out.values = g.camera;
    else
      out.values.assign(p.parameters.size(), 0.0);  // step: the render is flat in it
    d.groups.push_back(std::move(out));
  }
  return d;
}

}  // namespace ivr
