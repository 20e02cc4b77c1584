// ivr/tf_parameters.hpp — a transfer function's parameters as rows (the TF gradient's layout, what
// reconstructions optimise and write as PREFIX_tf.npy), read and written by the TF kinds' one
// registry (lib/scene/tf_kinds.hpp).
#pragma once
#include <cstddef>
#include <vector>

#include "ivr/export.h"
#include "ivr/scene.hpp"

namespace ivr {

// Shape of the TF gradient: identity → 1 x 2 (extinction_scale, color_scale); piecewise_linear
// and table → rows x 4 [r, g, b, extinction]; gaussian → rows x 6 [r, g, b, extinction, mean,
// width]. Where the TF is not differentiable (at a control point's density, at a table entry)
// the derivative is one-sided: the segment [d_k, d_k+1) holding the density is used.
IVR_API std::vector<std::size_t> tf_gradient_shape(const TransferFunction& tf);
// The TF's parameters in that layout, row-major (what a "tf" gradient is the derivative by), and
// back; set_tf_parameters throws ivr::Error(invalid_argument) for a count that does not fit.
IVR_API std::vector<double> tf_parameters(const TransferFunction& tf);
IVR_API void set_tf_parameters(TransferFunction& tf, const std::vector<double>& values);

}  // namespace ivr
