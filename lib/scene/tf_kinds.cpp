// tf_kinds.cpp — the TF kinds' registry and the parameter rows read and written through it.
#include "scene/tf_kinds.hpp"

#include <limits>

#include "ivr/error.hpp"
#include "ivr_constants.h"

namespace ivr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

constexpr TfColumnInfo kRed{TfColumn::red, "r", 0, 1, false, TfScale::unit};
constexpr TfColumnInfo kGreen{TfColumn::green, "g", 0, 1, false, TfScale::unit};
constexpr TfColumnInfo kBlue{TfColumn::blue, "b", 0, 1, false, TfScale::unit};
constexpr TfColumnInfo kExtinction{TfColumn::extinction, "extinction", 0, kInf, false,
                                   TfScale::largest_extinction};
constexpr TfColumnInfo kMean{TfColumn::mean, "mean", -kInf, kInf, false, TfScale::density};
constexpr TfColumnInfo kWidth{TfColumn::width, "width", 1e-6, kInf, true, TfScale::density};

}  // namespace

const std::vector<TfKindInfo>& tf_kinds() {
  static const std::vector<TfKindInfo> kinds = {
      {TfKind::identity,
       "identity",
       0,
       {{TfColumn::extinction_scale, "extinction_scale", 0, kInf, false, TfScale::own_magnitude},
        {TfColumn::color_scale, "color_scale", 0, kInf, false, TfScale::own_magnitude}}},
      {TfKind::piecewise_linear,
       "piecewise_linear",
       IVR_TF_STRIDE_PIECEWISE_LINEAR,
       {kRed, kGreen, kBlue, kExtinction}},
      {TfKind::table, "table", IVR_TF_STRIDE_TABLE, {kRed, kGreen, kBlue, kExtinction}},
      {TfKind::gaussian,
       "gaussian",
       IVR_TF_STRIDE_GAUSSIAN,
       {kRed, kGreen, kBlue, kExtinction, kMean, kWidth}},
  };
  return kinds;
}

const TfKindInfo& tf_kind_info(TfKind kind) {
  for (const TfKindInfo& k : tf_kinds())
    if (k.kind == kind) return k;
  throw Error(Status::invalid_argument, "unknown TF kind " + std::to_string(int(kind)));
}

const TfKindInfo* find_tf_kind(const std::string& name) {
  for (const TfKindInfo& k : tf_kinds())
    if (name == k.name) return &k;
  return nullptr;
}

std::string tf_kind_names() {
  std::string out;
  for (const TfKindInfo& k : tf_kinds()) out += std::string(out.empty() ? "" : ", ") + k.name;
  return out;
}

const char* tf_kind_name(TfKind kind) { return tf_kind_info(kind).name; }

std::size_t tf_rows(const TransferFunction& tf) {
  switch (tf.kind) {
    case TfKind::identity:
      return 1;
    case TfKind::piecewise_linear:
      return tf.points.size();
    case TfKind::table:
      return tf.entries.size();
    case TfKind::gaussian:
      return tf.gaussians.size();
  }
  return 0;
}

double& tf_value(TransferFunction& tf, std::size_t row, TfColumn column) {
  switch (column) {
    case TfColumn::extinction_scale:
      return tf.extinction_scale;
    case TfColumn::color_scale:
      return tf.color_scale;
    default:
      break;
  }
  const int channel = column == TfColumn::red ? 0 : column == TfColumn::green ? 1 : 2;
  const bool colour = column == TfColumn::red || column == TfColumn::green ||
                      column == TfColumn::blue;
  switch (tf.kind) {
    case TfKind::piecewise_linear:
      return colour ? tf.points.at(row).color[channel] : tf.points.at(row).extinction;
    case TfKind::table:  // entries are [r, g, b, sigma]
      return tf.entries.at(row)[colour ? channel : 3];
    case TfKind::gaussian: {
      TfGaussian& g = tf.gaussians.at(row);
      return colour ? g.color[channel]
             : column == TfColumn::extinction ? g.extinction
             : column == TfColumn::mean       ? g.mean
                                              : g.width;
    }
    case TfKind::identity:
      break;
  }
  throw Error(Status::invalid_argument, std::string("a ") + tf_kind_name(tf.kind) +
                                            " TF has no such parameter column");
}

}  // namespace ivr
