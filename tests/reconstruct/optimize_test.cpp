// optimize_test.cpp — the device optimisers against a double-precision host implementation of
// Adam and SGD with momentum (schedules, bias correction, box projection), convergence on a
// bounded quadratic, bit-for-bit resumption from a saved state, and the option errors.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "test_support.hpp"

namespace ivr {
namespace {

std::vector<double> signed_uniform(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> v(n);
  for (double& x : v) x = 2.0 * double(rng() >> 11) * 0x1.0p-53 - 1.0;
  return v;
}

// The textbook updates in double precision, written independently of the kernels.
struct HostOptimizer {
  OptimizerOptions o;
  std::vector<double> m, v;
  int t = 0;
  HostOptimizer(const OptimizerOptions& options, std::size_t n) : o(options), m(n), v(n) {}
  void step(std::vector<double>& x, const std::vector<double>& g) {
    const double lr = learning_rate(o, t);
    ++t;
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (o.kind == OptimizerKind::adam) {
        m[i] = o.beta1 * m[i] + (1 - o.beta1) * g[i];
        v[i] = o.beta2 * v[i] + (1 - o.beta2) * g[i] * g[i];
        const double mhat = m[i] / (1 - std::pow(o.beta1, t));
        const double vhat = v[i] / (1 - std::pow(o.beta2, t));
        x[i] -= lr * mhat / (std::sqrt(vhat) + o.epsilon);
      } else {
        m[i] = o.momentum * m[i] + g[i];
        x[i] -= lr * m[i];
      }
      x[i] = std::min(std::max(x[i], o.lower), o.upper);
    }
  }
};

struct Case {
  OptimizerKind kind;
  Schedule schedule;
  Precision precision;
};

class OptimizerTest : public ::testing::TestWithParam<Case> {};

TEST_P(OptimizerTest, MatchesTheHostUpdates) {
  const Case c = GetParam();
  if (c.precision == Precision::f64 && !test::device().info().fp64) GTEST_SKIP() << "no fp64";
  OptimizerOptions o;
  o.kind = c.kind;
  o.schedule = c.schedule;
  o.lr = 0.05;
  o.step_every = 7;
  o.total_iterations = 20;
  o.min_lr = 0.001;
  o.lower = -0.3;
  o.upper = 0.5;
  const std::size_t n = 1000;
  Optimizer device_opt(test::device(), n, o, c.precision);
  HostOptimizer host_opt(o, n);
  std::vector<double> x = signed_uniform(n, 1), expected = x;
  for (double& v : x) v = std::min(std::max(v, o.lower), o.upper);
  expected = x;
  for (int k = 0; k < 25; ++k) {
    const std::vector<double> g = signed_uniform(n, 100 + k);
    device_opt.step(x, g);
    host_opt.step(expected, g);
  }
  EXPECT_EQ(device_opt.iterations(), 25);
  const double tol = c.precision == Precision::f64 ? 1e-12 : 2e-5;
  int at_bounds = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_NEAR(x[i], expected[i], tol) << "parameter " << i;
    at_bounds += x[i] == o.lower || x[i] == o.upper;
  }
  EXPECT_GT(at_bounds, 0) << "the projection was never exercised";
}

INSTANTIATE_TEST_SUITE_P(
    Kinds, OptimizerTest,
    ::testing::Values(Case{OptimizerKind::adam, Schedule::constant, Precision::f32},
                      Case{OptimizerKind::adam, Schedule::cosine, Precision::f64},
                      Case{OptimizerKind::sgd, Schedule::step, Precision::f32},
                      Case{OptimizerKind::sgd, Schedule::cosine, Precision::f64}),
    [](const auto& info) {
      return std::string(optimizer_name(info.param.kind)) + "_" +
             schedule_name(info.param.schedule) + "_" + test::name(info.param.precision);
    });

TEST(Optimizer, SchedulesFollowTheirClosedForms) {
  OptimizerOptions o;
  o.lr = 0.1;
  EXPECT_EQ(learning_rate(o, 12345), 0.1);
  o.schedule = Schedule::step;
  o.step_every = 100;
  o.step_gamma = 0.5;
  EXPECT_DOUBLE_EQ(learning_rate(o, 99), 0.1);
  EXPECT_DOUBLE_EQ(learning_rate(o, 100), 0.05);
  EXPECT_DOUBLE_EQ(learning_rate(o, 250), 0.025);
  o.schedule = Schedule::cosine;
  o.total_iterations = 50;
  o.min_lr = 0.01;
  EXPECT_DOUBLE_EQ(learning_rate(o, 0), 0.1);
  EXPECT_NEAR(learning_rate(o, 25), 0.055, 1e-15);
  EXPECT_DOUBLE_EQ(learning_rate(o, 50), 0.01);
  EXPECT_DOUBLE_EQ(learning_rate(o, 80), 0.01);
}

// ½ Σ a_i (x_i − c_i)² with some minimisers outside [0, 1]: both optimisers reach the projected
// minimiser clamp(c, 0, 1).
TEST(Optimizer, ConvergesOnABoundedQuadratic) {
  const std::size_t n = 64;
  std::vector<double> a(n), c = signed_uniform(n, 9);
  for (std::size_t i = 0; i < n; ++i) a[i] = 0.5 + 0.02 * double(i), c[i] *= 1.5;
  for (OptimizerKind kind : {OptimizerKind::adam, OptimizerKind::sgd}) {
    OptimizerOptions o;
    o.kind = kind;
    o.lr = kind == OptimizerKind::adam ? 0.05 : 0.1;
    o.lower = 0;
    o.upper = 1;
    Optimizer opt(test::device(), n, o);
    std::vector<double> x(n, 0.5), g(n);
    for (int k = 0; k < 600; ++k) {
      for (std::size_t i = 0; i < n; ++i) g[i] = a[i] * (x[i] - c[i]);
      opt.step(x, g);
    }
    for (std::size_t i = 0; i < n; ++i)
      EXPECT_NEAR(x[i], std::min(std::max(c[i], 0.0), 1.0), 2e-3)
          << optimizer_name(kind) << " parameter " << i;
  }
}

TEST(Optimizer, ResumesBitForBitFromItsState) {
  OptimizerOptions o;
  o.schedule = Schedule::cosine;
  o.total_iterations = 30;
  const std::size_t n = 257;
  std::vector<double> x = signed_uniform(n, 3);
  Optimizer straight(test::device(), n, o);
  for (int k = 0; k < 10; ++k) straight.step(x, signed_uniform(n, 50 + k));
  const Optimizer::State saved = straight.state();
  std::vector<double> resumed_x = x;
  for (int k = 10; k < 20; ++k) straight.step(x, signed_uniform(n, 50 + k));
  Optimizer resumed(test::device(), n, o);
  resumed.restore(saved);
  EXPECT_EQ(resumed.iterations(), 10);
  for (int k = 10; k < 20; ++k) resumed.step(resumed_x, signed_uniform(n, 50 + k));
  EXPECT_EQ(resumed_x, x);
  Optimizer::State wrong = saved;
  wrong.second.pop_back();
  EXPECT_THROW(resumed.restore(wrong), Error);
}

TEST(Optimizer, RefusesBadOptionsWithTheirNames) {
  auto message = [](OptimizerOptions o) {
    try {
      validate_optimizer(o);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  OptimizerOptions o;
  o.lr = -1;
  EXPECT_NE(message(o).find("lr"), std::string::npos);
  o = {};
  o.beta2 = 1;
  EXPECT_NE(message(o).find("beta2"), std::string::npos);
  o = {};
  o.lower = 1, o.upper = 0;
  EXPECT_NE(message(o).find("lower <= upper"), std::string::npos);
  o = {};
  o.schedule = Schedule::cosine;
  EXPECT_NE(message(o).find("total_iterations"), std::string::npos);
  EXPECT_THROW(parse_optimizer("lbfgs2"), Error);
  EXPECT_THROW(parse_schedule("linear"), Error);
  EXPECT_EQ(parse_optimizer("sgd"), OptimizerKind::sgd);
  Optimizer opt(test::device(), 4, {});
  std::vector<double> x(3);
  EXPECT_THROW(opt.step(x, std::vector<double>(4)), Error);
  EXPECT_THROW(Optimizer(test::device(), 0, {}), Error);
}

}  // namespace
}  // namespace ivr
