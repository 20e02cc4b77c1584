// reconstruct_params.hpp — the parameters a reconstruction optimises: the TF's values in the
// gradient layout with their bounds and scales, and the density scale the default lr follows.
#pragma once
#include <vector>

#include "ivr/adjoint.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// Per parameter of tf_parameters (ivr/adjoint.hpp): the box it is kept in and the scale that
// normalises it for the optimiser (colours 1, extinctions their largest value, Gaussian means and
// widths the density scale), so one learning rate fits every column.
struct TfBounds {
  std::vector<double> lower, upper, scale;
};
TfBounds tf_bounds(const TransferFunction& tf, double density_scale);

// The span of densities the TF distinguishes (its last control point, table end, Gaussians'
// mean + 2 widths; identity: the volume's maximum), at least 1e-3: the unit of density steps.
double density_scale(const Scene& scene);
// The same with the identity TF's volume maximum given (`largest`: over slabs the whole volume's,
// gathered from the workers, not one slab's).
double density_scale(const TransferFunction& tf, double largest);
// The largest of the volume's densities (0 for none).
double largest_density(const Volume& volume);

}  // namespace ivr
