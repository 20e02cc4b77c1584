// gradient.cpp — gradients by named group on a session: the parameters each group stands
// for, the planner's choice of mode, the run in that mode (lib/jacobian/jacobian.cpp or lib/adjoint/adjoint.cpp)
// and each group's array; and the one-shot gradient().
#include "ivr/gradient.hpp"

#include <algorithm>
#include <cctype>
#include <set>
#include <sstream>

#include "ivr/error.hpp"
#include "ivr/jacobian.hpp"
#include "session/session.hpp"
#include "render/render.hpp"
#include "adjoint/adjoint.hpp"
#include "jacobian/jacobian.hpp"
#include "gradient/gradient.hpp"

#include "brick/bricked_gradient.hpp"
#include "gradient/parameter_groups.hpp"

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

// What one group needs: its forward-mode parameters (listed only for the groups whose count is
// small or given: "density" stands for every voxel, which only forward mode would list), its
// output shape, and whether the adjoint computes it.
struct GroupPlan {
  std::string name, asked;
  std::vector<Parameter> parameters;  // empty for "density"
  std::size_t count = 0;
  std::vector<std::int64_t> shape;
  bool adjoint = true;
  std::vector<Parameter> forward_parameters(const Scene& scene) const {
    return asked == "density" ? parameters_of(scene, asked) : parameters;
  }
};

GroupPlan plan_group(const Scene& scene, const std::string& g) {
  const ParameterGroupInfo* info = find_parameter_group(g);
  if (!info) throw bad_group(unknown_group_message(g));
  const bool voxels = std::string(info->name) == "voxels";
  if (g == "camera" && scene.has_ray_list())
    throw bad_group("camera: the scene's rays are a ray list, which has no camera to "
                    "differentiate (ask for density, tf, background, …)");
  GroupPlan p;
  p.name = voxels ? "voxels" : g;
  p.asked = g;
  if (g != "density") p.parameters = parameters_of(scene, g);
  p.count = g == "density" ? scene.volume.voxel_count() : p.parameters.size();
  if (g == "density")
    p.shape = {scene.volume.nz, scene.volume.ny, scene.volume.nx};
  else if (g == "tf")
    p.shape = {std::int64_t(tf_gradient_shape(scene.tf)[0]),
               std::int64_t(tf_gradient_shape(scene.tf)[1])};
  else if (g == "camera")
    p.shape = {std::int64_t(scene.cameras.size()), 7};
  else if (g == "rays")
    p.shape = {std::int64_t(scene.rays.count()), RayList::kColumns};
  else
    p.shape = {std::int64_t(p.parameters.size())};
  p.adjoint = info->adjoint;
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

SessionGradient session_gradient(Session::Impl& s, const DeviceArray& target,
                                 const GradientRequest& request, const ShareDecision& share) {
  if (request.mode != Mode::automatic && request.mode != Mode::forward &&
      request.mode != Mode::adjoint)
    throw bad_group("unknown mode " + std::to_string(int(request.mode)));
  std::vector<GroupPlan> plans;
  std::size_t forward_parameters = 0;  // the lanes of the passes other than the rays' own
  bool adjoint_possible = true, per_ray = false, rays = false;
  for (const std::string& g : request.wrt) {
    plans.push_back(plan_group(s.scene, g));
    rays = rays || plans.back().name == "rays";
    if (plans.back().name != "rays") forward_parameters += plans.back().count;
    adjoint_possible = adjoint_possible && plans.back().adjoint;
    // Camera, ray and voxel lanes (density's too, in forward mode) march one ray per work-item
    // (forward_cost).
    per_ray = per_ray || plans.back().name == "camera" || plans.back().name == "voxels" ||
              plans.back().name == "density" || plans.back().name == "rays";
  }
  if (plans.empty()) throw bad_group("no group asked for");
  if (request.mode == Mode::adjoint)
    for (const GroupPlan& p : plans)
      if (!p.adjoint)
        throw Error(Status::invalid_argument,
                    "mode adjoint cannot compute group '" + p.name + "' (forward mode only)");
  // The step once for both the plan and the mode that runs (a tolerance is estimated here).
  const double step = s.integrator().step;
  if (!s.cost) s.cost = load_cost_model(s.dev.info);
  SessionGradient out;
  out.plan = plan_gradient(*s.cost, s.scene, forward_parameters, true, adjoint_possible,
                           request.mode, step, per_ray);
  if (rays) {  // a ray list's rays: one pass of 8 lanes more, whatever their count
    Plan& p = out.plan;
    const double others = forward_cost(*s.cost, forward_parameters, nullptr, nullptr, per_ray);
    const double own = forward_cost(*s.cost, RayList::kColumns, nullptr, nullptr, true);
    const bool alone = forward_parameters == 0;
    p.forward_seconds *= (alone ? own : others + own) / others;
    p.passes = alone ? 1 : p.passes + 1;
    p.lanes = alone ? std::size_t(RayList::kColumns)
                    : std::max<std::size_t>(p.lanes, RayList::kColumns);
  }
  // A data-parallel worker: the fixed-point decision, agreed with the others (a collective).
  const FixedShare* fixed_share = share ? share(out.plan.mode) : nullptr;
  OperationRecord& op = s.begin("gradient");
  cl_call("splitting the gradient into its groups", [&] {
    if (out.plan.mode == Mode::forward) {
      std::vector<Parameter> all;
      for (const GroupPlan& p : plans) {
        const std::vector<Parameter> listed = p.forward_parameters(s.scene);
        all.insert(all.end(), listed.begin(), listed.end());
      }
      const JacobianResult t = enqueue_jacobian(s, lanes_of(s.scene, all), &target, false,
                                               request.loss, op);
      out.loss = t.loss;
      // Each group's slice of the one gradient vector, copied into an array of its own.
      const std::size_t size = dtype_size(t.gradient.dtype());
      std::size_t at = 0;
      for (const GroupPlan& p : plans) {
        DeviceArray g = s.output("group " + p.name, p.shape, t.gradient.dtype(), "a gradient");
        if (p.count > 0) {
          op.events.push_back(cl::Event());
          s.dev.queue.enqueueCopyBuffer(buffer_of(t.gradient), buffer_of(g), at * size, 0,
                                        p.count * size, nullptr, &op.events.back());
          mark_written(g, op.events.back());
        }
        at += p.count;
        out.groups.emplace_back(p.name, g);
      }
      return;
    }
    AdjointRequest r;
    r.loss = request.loss;
    r.deterministic = request.deterministic || fixed_share;
    r.share = fixed_share;
    r.density = r.tf = r.background = r.camera = false;
    for (const GroupPlan& p : plans) {
      r.density = r.density || p.name == "density" || p.name == "voxels";
      r.tf = r.tf || p.name == "tf" || p.name == "scales";
      r.background = r.background || p.name == "background";
      r.camera = r.camera || p.name == "camera";
    }
    const AdjointResult a = enqueue_adjoint(s, target, r, op);
    out.loss = a.loss;
    out.atomics = a.atomics;
    for (const GroupPlan& p : plans) {
      DeviceArray g;
      if (p.name == "density") {
        g = a.density;
      } else if (p.name == "voxels") {  // the listed voxels, gathered on the device
        std::vector<cl_long> index;
        for (const Parameter& q : p.parameters) index.push_back(cl_long(q.index));
        const cl::Buffer indices =
            s.dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, index.size() * sizeof(cl_long),
                         index.data(), "the voxel list");
        g = s.output("group voxels", p.shape, a.density.dtype(), "the voxels' gradient");
        op.events.push_back(
            s.arrays.gather(buffer_of(a.density), indices, int(index.size()), buffer_of(g)));
        mark_written(g, op.events.back());
      } else if (p.name == "tf" || p.name == "scales") {
        g = p.shape == a.tf.shape() ? a.tf : reshape(a.tf, p.shape);
      } else if (p.name == "background") {
        g = a.background;
      } else if (p.name == "camera") {
        g = a.camera;
      } else {  // step: the render is flat in it
        g = DeviceArray(s.device, p.shape, s.arrays.acc_dtype());
      }
      out.groups.emplace_back(p.name, g);
    }
  });
  op.stats.mode = out.plan.mode;
  return out;
}

std::vector<std::size_t> group_shape(const Scene& scene, const std::string& g) {
  const GroupPlan p = plan_group(scene, g);
  return std::vector<std::size_t>(p.shape.begin(), p.shape.end());
}

Gradient gradient(Device& device, const Scene& scene, const Image& target,
                  const std::vector<std::string>& groups, const GradientOptions& o) {
  if (o.workers > 1 || o.worker != 0) return gradient_shared(device, scene, target, groups, o);
  return gradient_one(device, scene, target, groups, o);
}

Gradient gradient_one(Device& device, const Scene& scene, const Image& target,
                      const std::vector<std::string>& groups, const GradientOptions& o,
                      const ShareDecision& share) {
  // The groups first: a bad --wrt is reported before any device work.
  for (const std::string& g : groups) plan_group(scene, g);
  // (Out of core the endpoint schemes' bricks hold a halo of a step: brick_halo.)
  const BrickPlan bricks =
      plan_render(device, scene, o.precision, 0, true,
                  brick_halo(scene, o.step != 0 ? o.step : scene.integrator.step, o.deterministic));
  if (bricks.layout.edge) {
    if (!share) return gradient_bricked(device, scene, target, groups, o, bricks);
    // A data-parallel worker out of core: fixed point where every worker runs the adjoint alone
    // (the forward lanes' groups would be the share's own means, not parts of the batch's) — each
    // share then sums its rays' segments at the batch's scale, and the shares' integer sums, over
    // bricks of any edge or in core, are the one process's.
    bool adjoint_alone = o.mode != Mode::forward;
    for (const std::string& g : groups)
      adjoint_alone = adjoint_alone && (g == "density" || g == "tf" || g == "background");
    const FixedShare* fixed = share(adjoint_alone ? Mode::adjoint : Mode::forward);
    GradientOptions mine = o;
    mine.deterministic = fixed != nullptr;
    return gradient_bricked(device, scene, target, groups, mine, bricks, nullptr, nullptr, nullptr,
                            fixed);
  }
  Session session = one_shot_session(device, scene, {o.precision, o.step});
  session.set_target(target);
  Session::Impl& s = session.impl();
  GradientRequest request;
  request.wrt = groups;
  request.mode = o.mode;
  request.loss = o.loss;
  request.deterministic = o.deterministic;
  const SessionGradient g = session_gradient(s, s.target, request, share);
  Gradient d;
  d.step = s.integrator().step;
  d.plan = g.plan;
  d.loss = g.loss.to_doubles()[0];
  d.atomics = g.atomics;
  for (std::size_t i = 0; i < g.groups.size(); ++i) {
    const GroupPlan p = plan_group(s.scene, groups[i]);
    d.groups.push_back({p.name, std::vector<std::size_t>(p.shape.begin(), p.shape.end()),
                        g.groups[i].second.to_doubles()});
    d.parameters += p.count;
  }
  const OperationStats st = session.last_stats();
  d.kernel_seconds = st.kernel_seconds;
  d.device_bytes = st.device_bytes;
  d.deterministic = st.deterministic;
  return d;
}

}  // namespace ivr
