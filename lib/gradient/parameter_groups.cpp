// parameter_groups.cpp — the parameter groups' registry.
#include "gradient/parameter_groups.hpp"

namespace ivr {

const std::vector<ParameterGroupInfo>& parameter_groups() {
  static const std::vector<ParameterGroupInfo> groups = {
      {"density", true, "every voxel (nz, ny, nx)"},
      {"tf", true, "the TF's parameter rows (ivr/tf_parameters.hpp)"},
      {"tf_points", false, "the densities of a piecewise-linear TF's control points"},
      {"scales", true, "the identity TF's extinction and colour scales"},
      {"background", true, "the background (1 value for absorption, 3 for emission)"},
      {"camera", true, "every view's [eye xyz, target xyz, fov_y]"},
      {"step", true, "the integrator step (derivative 0: it enters through the sample count)"},
      {"voxels", true, "the listed voxels, voxels:LIST of indices and ranges a-b, x fastest"},
      {"rays", false,
       "a ray list's rays (R, 8): [origin xyz, direction xyz (normalised), t_start, t_end]"},
  };
  return groups;
}

const ParameterGroupInfo* find_parameter_group(const std::string& asked) {
  const std::string name = asked.rfind("voxels:", 0) == 0 ? "voxels" : asked;
  if (name == "voxels" && asked == "voxels") return nullptr;  // the list is required
  for (const ParameterGroupInfo& g : parameter_groups())
    if (name == g.name) return &g;
  return nullptr;
}

std::string unknown_group_message(const std::string& asked) {
  std::string known;
  for (const ParameterGroupInfo& g : parameter_groups())
    known += std::string(known.empty() ? "" : ", ") + g.name +
             (std::string(g.name) == "voxels" ? ":LIST" : "");
  return "unknown parameter group '" + asked + "' (known: " + known + ")";
}

}  // namespace ivr
