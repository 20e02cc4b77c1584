// parameter_groups.hpp — the one registry of the parameter groups a gradient or Jacobian is taken
// with respect to (ivr gradient --wrt, GradientRequest::wrt, ivr_gradient's wrt, Python's wrt).
#pragma once
#include <string>
#include <vector>

namespace ivr {

struct ParameterGroupInfo {
  const char* name;  // as given; "voxels" takes ":LIST"
  bool adjoint;      // the adjoint computes it (else forward mode only)
  const char* what;  // for help texts
};

const std::vector<ParameterGroupInfo>& parameter_groups();
// The group `asked` names ("voxels:1,2" → voxels), or nullptr.
const ParameterGroupInfo* find_parameter_group(const std::string& asked);
// "unknown parameter group 'x' (known: density, tf, …, voxels:LIST)".
std::string unknown_group_message(const std::string& asked);

}  // namespace ivr
