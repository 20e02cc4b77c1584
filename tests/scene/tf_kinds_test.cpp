// tf_kinds_test.cpp — the TF kinds' registry: every kind's JSON name reads and writes that kind,
// its parameter rows go out and back unchanged in the documented column order, and the kernels'
// row widths are the shared constants.
#include "scene/tf_kinds.hpp"

#include <gtest/gtest.h>

#include "ivr/error.hpp"
#include "ivr/tf_parameters.hpp"
#include "ivr_constants.h"
#include "reconstruct/reconstruct_params.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

TransferFunction example(TfKind kind) {
  TransferFunction tf;
  tf.kind = kind;
  tf.extinction_scale = 3;
  tf.color_scale = 0.5;
  tf.points = {{0.0, {0.1, 0.2, 0.3}, 4}, {1.0, {0.5, 0.6, 0.7}, 8}};
  tf.entries = {{0.1, 0.2, 0.3, 4}, {0.4, 0.5, 0.6, 7}, {0.7, 0.8, 0.9, 9}};
  tf.range = {0, 1};
  tf.gaussians = {{0.3, 0.1, {0.2, 0.4, 0.6}, 5}};
  return tf;
}

TEST(TfKinds, NamesReadAndWriteTheirKind) {
  EXPECT_EQ(tf_kinds().size(), 4u);
  for (const TfKindInfo& k : tf_kinds()) {
    EXPECT_EQ(find_tf_kind(k.name), &k);
    const TransferFunction tf = example(k.kind);
    EXPECT_EQ(parse_tf(tf_json(tf)).kind, k.kind) << k.name;
  }
  EXPECT_EQ(find_tf_kind("spline"), nullptr);
  try {
    parse_tf(R"({"type": "spline"})");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "(known: identity, piecewise_linear, table, gaussian)")) << e.what();
  }
  EXPECT_EQ(tf_kind_info(TfKind::piecewise_linear).device_stride, IVR_TF_STRIDE_PIECEWISE_LINEAR);
  EXPECT_EQ(tf_kind_info(TfKind::gaussian).device_stride, IVR_TF_STRIDE_GAUSSIAN);
}

TEST(TfKinds, ParameterRowsInTheDocumentedOrderAndBack) {
  const TransferFunction pl = example(TfKind::piecewise_linear);
  EXPECT_EQ(tf_parameters(pl), (std::vector<double>{0.1, 0.2, 0.3, 4, 0.5, 0.6, 0.7, 8}));
  const TransferFunction g = example(TfKind::gaussian);
  EXPECT_EQ(tf_parameters(g), (std::vector<double>{0.2, 0.4, 0.6, 5, 0.3, 0.1}));  // r g b e mean width
  EXPECT_EQ(tf_parameters(example(TfKind::identity)), (std::vector<double>{3, 0.5}));
  EXPECT_EQ(tf_gradient_shape(example(TfKind::table)), (std::vector<std::size_t>{3, 4}));
  for (const TfKindInfo& k : tf_kinds()) {
    TransferFunction tf = example(k.kind);
    std::vector<double> v = tf_parameters(tf);
    for (double& x : v) x = x * 2 + 1;
    set_tf_parameters(tf, v);
    EXPECT_EQ(tf_parameters(tf), v) << k.name;
    v.pop_back();
    EXPECT_THROW(set_tf_parameters(tf, v), Error) << k.name;
  }
  // Bounds by column: colours in [0, 1], extinctions >= 0, a Gaussian's width > 0.
  const TfBounds b = tf_bounds(g, 2.0);
  EXPECT_EQ(b.upper[0], 1);
  EXPECT_EQ(b.lower[3], 0);
  EXPECT_EQ(b.scale[3], 5);    // the largest extinction
  EXPECT_EQ(b.lower[5], 2e-6);  // 1e-6 × the density scale
  EXPECT_EQ(b.scale[4], 2);
}

}  // namespace
}  // namespace ivr::test
