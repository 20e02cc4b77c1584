// tf_kinds.hpp — the one registry of transfer-function kinds: the JSON name, the kernels' row
// layout, and the parameter columns (names, bounds, scales) that the TF gradient, tf_parameters,
// reconstructions and the front ends share.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "ivr/scene.hpp"

namespace ivr {

// One column of a TF's parameter rows (the TF gradient's layout, ivr/tf_parameters.hpp).
enum class TfColumn { red, green, blue, extinction, mean, width, extinction_scale, color_scale };

// What the optimiser normalises a column by (reconstruct_params.cpp: one learning rate for all).
enum class TfScale { unit, largest_extinction, density, own_magnitude };

struct TfColumnInfo {
  TfColumn column;
  const char* name;
  double lower, upper;  // the box a reconstruction keeps it in
  bool lower_in_density_units;  // lower × the density scale (a Gaussian's width > 0)
  TfScale scale;
};

struct TfKindInfo {
  TfKind kind;
  const char* name;    // the JSON "type", and in labels and messages
  int device_stride;   // values per row of the kernels' TF buffer (IVR_TF_STRIDE_*; 0: scalars)
  std::vector<TfColumnInfo> columns;  // one parameter row
};

const std::vector<TfKindInfo>& tf_kinds();
const TfKindInfo& tf_kind_info(TfKind kind);
// The kind of a JSON "type", or nullptr; tf_kind_names() lists them for messages.
const TfKindInfo* find_tf_kind(const std::string& name);
std::string tf_kind_names();
const char* tf_kind_name(TfKind kind);

// Parameter rows of a TF (1 for identity: its two scales).
std::size_t tf_rows(const TransferFunction& tf);
// The value in row `row`, column `column` of the TF (a reference into it).
double& tf_value(TransferFunction& tf, std::size_t row, TfColumn column);

}  // namespace ivr
