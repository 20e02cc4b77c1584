// tf_parameters.cpp — a TF's parameter rows through the TF kinds' registry (ivr/tf_parameters.hpp).
#include "ivr/tf_parameters.hpp"

#include <string>

#include "ivr/error.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr {

std::vector<std::size_t> tf_gradient_shape(const TransferFunction& tf) {
  return {tf_rows(tf), tf_kind_info(tf.kind).columns.size()};
}

std::vector<double> tf_parameters(const TransferFunction& tf) {
  TransferFunction& t = const_cast<TransferFunction&>(tf);  // tf_value is read only here
  std::vector<double> v;
  for (std::size_t r = 0; r < tf_rows(tf); ++r)
    for (const TfColumnInfo& c : tf_kind_info(tf.kind).columns)
      v.push_back(tf_value(t, r, c.column));
  return v;
}

void set_tf_parameters(TransferFunction& tf, const std::vector<double>& values) {
  const std::vector<std::size_t> shape = tf_gradient_shape(tf);
  if (values.size() != shape[0] * shape[1])
    throw Error(Status::invalid_argument, "TF values: " + std::to_string(values.size()) +
                                              " values for a TF of " +
                                              std::to_string(shape[0] * shape[1]));
  std::size_t i = 0;
  for (std::size_t r = 0; r < shape[0]; ++r)
    for (const TfColumnInfo& c : tf_kind_info(tf.kind).columns) tf_value(tf, r, c.column) = values[i++];
}

}  // namespace ivr
