// private_sums_test.cpp — the CPU packet adjoint's private sums (kernels/private_sums.cl:
// work-groups of one work-item taking packets from a counter, each adding into its own copy of
// the density gradient and its own local TF accumulator without atomics): the choice per device
// and operation, its switch and its errors; and on the device, the gradients against the atomic
// adds' for every integrator, the copies left clean for the next call (a second call and a larger
// volume in the same session give the same gradient, not twice it), the TF gradient alone.
#include "adjoint/private_sums.hpp"

#include <gtest/gtest.h>

#include "adjoint/adjoint_support.hpp"
#include "ivr/session.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr::test {
namespace {

DeviceInfo cpu_with(int units, std::uint64_t memory) {
  DeviceInfo info;
  info.name = "a test CPU";
  info.type = "cpu";
  info.compute_units = units;
  info.global_memory = memory;
  info.max_allocation = memory / 2;
  return info;
}

// The benchmark's shape: 128³ voxels into 256² rays, float32, the packet adjoint's float sums.
PrivateSumsQuery benchmark_query() {
  PrivateSumsQuery q;
  q.packet = true;
  q.density = true;
  q.eligible = true;
  q.voxels = 128 * 128 * 128;
  q.real_size = 4;
  q.pixels = 256 * 256;
  q.longest_edge = 128;
  return q;
}

constexpr std::uint64_t kGiB = std::uint64_t(1) << 30;

TEST(PrivateSums, ChoiceFollowsTheOperationTheDeviceAndTheCost) {
  const ScopedEnv automatic("IVR_PRIVATE_SUMS", "auto");
  const DeviceInfo cpu = cpu_with(4, 16 * kGiB);
  PrivateSums p = private_sums_for(cpu, benchmark_query());
  EXPECT_TRUE(p.on);
  EXPECT_EQ(p.groups, 4);  // one work-group a compute unit
  EXPECT_EQ(p.copy_values, 128u * 128 * 128);
  EXPECT_EQ(p.bytes(4), 4u * 128 * 128 * 128 * 4);

  PrivateSumsQuery q = benchmark_query();
  q.voxels = 1001;  // padded to whole vectors of the sum kernel
  EXPECT_EQ(private_sums_for(cpu, q).copy_values, 1008u);

  q = benchmark_query();
  q.packet = false;  // one ray per work-item (GPUs): the atomics
  EXPECT_FALSE(private_sums_for(cpu, q).on);
  q = benchmark_query();
  q.eligible = false;  // the camera gradient, fixed point or the scatter cache
  EXPECT_FALSE(private_sums_for(cpu, q).on);

  q = benchmark_query();
  q.density = false;  // the TF gradient alone: private local sums, no copies
  p = private_sums_for(cpu, q);
  EXPECT_TRUE(p.on);
  EXPECT_EQ(p.copy_values, 0u);
  EXPECT_EQ(p.bytes(4), 0u);

  // Copies beyond a quarter of the memory, or beyond one allocation: the atomics.
  q = benchmark_query();
  q.voxels = std::size_t(512) * 512 * 512;
  q.longest_edge = 512;
  q.pixels = 1024 * 1024;
  EXPECT_TRUE(private_sums_for(cpu_with(4, 64 * kGiB), q).on);
  EXPECT_FALSE(private_sums_for(cpu_with(4, 4 * kGiB), q).on);
  DeviceInfo small_allocation = cpu_with(4, 64 * kGiB);
  small_allocation.max_allocation = kGiB;
  EXPECT_FALSE(private_sums_for(small_allocation, q).on);

  // A large volume seen by few rays: summing the copies would cost more than the atomics save
  // (512³ → 16² measured so: 112 against 82 ms on 2 cores), where 256³ → 64² still gains.
  q = benchmark_query();
  q.voxels = std::size_t(256) * 256 * 256;
  q.longest_edge = 256;
  q.pixels = 64 * 64;
  EXPECT_TRUE(private_sums_for(cpu, q).on);
  q.voxels = std::size_t(512) * 512 * 512;
  q.longest_edge = 512;
  q.pixels = 16 * 16;
  EXPECT_FALSE(private_sums_for(cpu, q).on);
  // ... and more compute units mean more copies to sum for the same adds.
  q = benchmark_query();
  q.pixels = 32 * 32;
  EXPECT_TRUE(private_sums_for(cpu_with(2, 16 * kGiB), q).on);
  EXPECT_FALSE(private_sums_for(cpu_with(64, 16 * kGiB), q).on);
}

TEST(PrivateSums, SwitchForcesOrRefusesWithOneLine) {
  const DeviceInfo cpu = cpu_with(4, 16 * kGiB);
  PrivateSumsQuery costly = benchmark_query();
  costly.voxels = std::size_t(256) * 256 * 256;
  costly.pixels = 8 * 8;
  {
    const ScopedEnv forced("IVR_PRIVATE_SUMS", "1");
    EXPECT_TRUE(private_sums_for(cpu, costly).on);  // forced where the default says no
    PrivateSumsQuery q = benchmark_query();
    q.eligible = false;
    try {
      private_sums_for(cpu, q);
      ADD_FAILURE() << "forced on where it cannot be";
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument);
      EXPECT_TRUE(has(e.what(), "IVR_PRIVATE_SUMS=1")) << e.what();
      EXPECT_FALSE(has(e.what(), "\n")) << e.what();
    }
    try {
      private_sums_for(cpu_with(4, kGiB / 2), costly);
      ADD_FAILURE() << "forced on where the copies do not fit";
    } catch (const Error& e) {
      EXPECT_TRUE(has(e.what(), "do not fit in a test CPU")) << e.what();
    }
  }
  {
    const ScopedEnv off("IVR_PRIVATE_SUMS", "0");
    EXPECT_FALSE(private_sums_for(cpu, benchmark_query()).on);
  }
  const ScopedEnv bad("IVR_PRIVATE_SUMS", "yes");
  try {
    private_sums_for(cpu, benchmark_query());
    ADD_FAILURE() << "a bad value was taken";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument);
    EXPECT_TRUE(has(e.what(), "IVR_PRIVATE_SUMS must be auto, 0 or 1, got 'yes'")) << e.what();
  }
}

struct Result {
  std::vector<double> loss, density, tf;
  std::string variant;
};

Result read(Session& session, const SessionGradient& g, bool density) {
  Result out;
  out.variant = session.last_stats().variant;
  out.loss = g.loss.to_doubles();
  if (density) out.density = g["density"].to_doubles();
  out.tf = g["tf"].to_doubles();
  return out;
}

GradientRequest request(bool density) {
  GradientRequest r;
  r.wrt = density ? std::vector<std::string>{"density", "tf"} : std::vector<std::string>{"tf"};
  r.mode = Mode::adjoint;
  return r;
}

Result gradient_with(const Scene& scene, const Image& target, Precision precision,
                     bool private_sums, bool density = true) {
  const ScopedEnv force("IVR_PRIVATE_SUMS", private_sums ? "1" : "0");
  SessionOptions so;
  so.precision = precision;
  Session session(device(), scene, so);
  session.set_target(target);
  const SessionGradient g = session.gradient(request(density));
  return read(session, g, density);
}

// |a − b| within `relative` of b's largest element, element by element.
::testing::AssertionResult close(const std::vector<double>& a, const std::vector<double>& b,
                                 double relative) {
  if (a.size() != b.size()) return ::testing::AssertionFailure() << "sizes differ";
  const double scale = max_abs(b);
  if (!(scale > 0)) return ::testing::AssertionFailure() << "the reference is zero";
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!(std::abs(a[i] - b[i]) <= relative * scale))
      return ::testing::AssertionFailure() << "element " << i << ": " << a[i] << " against " << b[i]
                                           << " (largest " << scale << ")";
  return ::testing::AssertionSuccess();
}

bool cpu_device() {
  return device().info().type == "cpu";
}

// Two integrators in float32 and one in float64 (every integrator and TF kind meets private sums
// in AdjointPacket's float sums, against the one-ray kernel's atomics): the same loss bit for bit,
// the gradients to the order of their float additions.
TEST(PrivateSums, GradientsAreTheAtomicAddsToRounding) {
  if (!cpu_device()) GTEST_SKIP() << "private sums serve the CPU packet adjoint";
  struct Case {
    Scheme scheme;
    Model model;
    Precision precision;
  };
  for (const Case c : {Case{Scheme::midpoint, Model::emission_absorption, Precision::f32},
                       Case{Scheme::exact, Model::absorption, Precision::f32},
                       Case{Scheme::trapezoid, Model::absorption, Precision::f64}}) {
    Scene s = two_view_scene(c.model, TfKind::piecewise_linear);
    for (Camera& cam : s.cameras) cam.width = 19, cam.height = 7;  // partial tiles
    s.integrator.scheme = c.scheme;
    const Image target = perturbed_target(s);
    const std::string what =
        std::string(scheme_name(c.scheme)) + (c.precision == Precision::f64 ? " f64" : " f32");
    const Result on = gradient_with(s, target, c.precision, true),
                 off = gradient_with(s, target, c.precision, false);
    EXPECT_TRUE(has(on.variant, "private_sums")) << what << ": " << on.variant;
    EXPECT_FALSE(has(off.variant, "private_sums")) << what << ": " << off.variant;
    EXPECT_EQ(on.loss, off.loss) << what;
    const double eps = c.precision == Precision::f64 ? 1e-12 : 2e-5;
    EXPECT_TRUE(close(on.density, off.density, eps)) << what << ": density gradient";
    EXPECT_TRUE(close(on.tf, off.tf, eps)) << what << ": TF gradient";
  }
}

// The sum kernel leaves the copies at 0: a second call in the same session gives the gradient
// again (not twice it; the same bits), and so does a call after a larger volume (new copies,
// filled once).
TEST(PrivateSums, CopiesAreCleanForTheNextCall) {
  if (!cpu_device()) GTEST_SKIP() << "private sums serve the CPU packet adjoint";
  const Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image target = perturbed_target(s);
  const Result off = gradient_with(s, target, Precision::f32, false);
  const ScopedEnv force("IVR_PRIVATE_SUMS", "1");
  Session session(device(), s);
  session.set_target(target);
  std::vector<double> first;
  for (int call = 0; call < 3; ++call) {
    const SessionGradient g = session.gradient(request(true));
    const std::vector<double> density = read(session, g, true).density;
    EXPECT_TRUE(close(density, off.density, 2e-5)) << "call " << call;
    // The groups take the same chunks of packets every call: the same bits.
    if (call == 0) first = density;
    EXPECT_EQ(density, first) << "call " << call;
  }
  // A larger volume: more voxels than the copies had.
  Scene larger = s;
  larger.volume = Volume();
  larger.volume.nx = 9, larger.volume.ny = 8, larger.volume.nz = 7;
  for (std::size_t i = 0; i < larger.volume.voxel_count(); ++i)
    larger.volume.data.push_back(float(0.2 + 0.6 * std::abs(std::sin(0.37 * double(i)))));
  session.set_volume(larger.volume);
  const Result want = [&] {
    const ScopedEnv atomics("IVR_PRIVATE_SUMS", "0");
    return gradient_with(larger, target, Precision::f32, false);
  }();
  for (int call = 0; call < 2; ++call) {
    const SessionGradient g = session.gradient(request(true));
    EXPECT_TRUE(close(read(session, g, true).density, want.density, 2e-5))
        << "larger volume, call " << call;
  }
}

// The TF gradient alone: one-item groups with their own local accumulators, no copies.
TEST(PrivateSums, TfGradientAlone) {
  if (!cpu_device()) GTEST_SKIP() << "private sums serve the CPU packet adjoint";
  for (TfKind kind : {TfKind::gaussian}) {  // its own per-ray cache of every Gaussian's sums
    const Scene s = two_view_scene(Model::emission_absorption, kind);
    const Image target = perturbed_target(s);
    const Result on = gradient_with(s, target, Precision::f32, true, false),
                 off = gradient_with(s, target, Precision::f32, false, false);
    EXPECT_TRUE(has(on.variant, "private_sums")) << on.variant;
    EXPECT_TRUE(close(on.tf, off.tf, 1e-5)) << tf_kind_name(kind);
  }
}

}  // namespace
}  // namespace ivr::test
