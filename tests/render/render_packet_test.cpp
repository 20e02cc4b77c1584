// render_packet_test.cpp — the CPU packet render (render.cl with 16 or 8 rays per work-item in
// vector lanes, kernels/rays.cl) against one ray per work-item ($IVR_PACKET=0): the same image bit
// for bit and the same sample counts, for every TF kind, both models, every integrator (midpoint,
// trapezoid, preintegrated, exact), both precisions, with and without empty-space skipping, and
// over edge cases of the packet (image widths not a multiple of the lanes, rays that miss, early
// termination, cameras inside the volume, orthographic views, one- and two-point TFs, densities
// exactly on the TF's points); and gradients whose primal march it made (lib/adjoint/adjoint.cpp)
// bit for bit those of the adjoint kernel's own march — its remaining radiance, C minus the
// prefix, needs that.
#include <gtest/gtest.h>

#include <cmath>

#include "test_support.hpp"

namespace ivr::test {
namespace {

struct Rendered {
  Image image;
  RenderStats stats;
};

Rendered render_with(const Scene& scene, bool packet, double step,
                     Precision precision = Precision::f32, EmptySpace skip = EmptySpace::automatic,
                     int brick_size = 0) {
  const ScopedEnv env("IVR_PACKET", packet ? "1" : "0");
  RenderOptions o;
  o.precision = precision;
  o.step = step;
  o.empty_space = skip;
  if (brick_size) o.brick_size = brick_size;
  Rendered r;
  r.image = render(device(), scene, o, &r.stats);
  return r;
}

template <class T>
void expect_bitwise(const std::vector<T>& a, const std::vector<T>& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_TRUE(std::isfinite(a[i])) << what << " element " << i;
    worst = std::max(worst, double(std::abs(a[i] - b[i])));
  }
  EXPECT_EQ(worst, 0.0) << what;  // bit for bit (the scalar exp in every lane)
}

void expect_same(const Scene& scene, double step, const std::string& what,
                 Precision precision = Precision::f32, EmptySpace skip = EmptySpace::automatic,
                 int brick_size = 0) {
  const Rendered a = render_with(scene, true, step, precision, skip, brick_size),
                 b = render_with(scene, false, step, precision, skip, brick_size);
  if (device().info().type == "cpu") {
    EXPECT_NE(a.stats.variant.find("packet"), std::string::npos) << what << ": " << a.stats.variant;
  }
  EXPECT_EQ(b.stats.variant.find("packet"), std::string::npos) << what;
  EXPECT_EQ(a.stats.skipped_empty, b.stats.skipped_empty) << what;
  EXPECT_EQ(a.stats.samples, b.stats.samples) << what;
  expect_bitwise(a.image.pixels, b.image.pixels, what);
  if (precision == Precision::f64) expect_bitwise(a.image.pixels_f64, b.image.pixels_f64, what);
}

TEST(RenderPacket, SameImageAsOneRayPerWorkItem) {
  for (const char* lanes : {"16", "8"}) {
    const ScopedEnv width("IVR_PACKET_LANES", lanes);
    Scene s = calibration_scene(24, 8);
    s.cameras[0].width = 37;  // whole 4x4 tiles and partial ones at the right and the bottom
    s.cameras[0].height = 23;
    Camera side = s.cameras[0];
    side.eye = {0.2, -1.4, 0.3};
    Camera inside = s.cameras[0];  // inside the box: rays start in the volume
    inside.eye = {0.1, 0.05, -0.1};
    inside.fov_y = 90;
    Camera ortho_view = ortho({0, 0, 2}, {0, 1, 0}, 37, 23, 1.6);  // wider than the box: misses
    s.cameras = {s.cameras[0], side, inside, ortho_view};
    for (double step : {0.5, 0.3})
      expect_same(s, step, "calibration, step " + std::to_string(step));

    Scene opaque = s;  // most rays terminate early, at different samples in a packet
    for (TfPoint& p : opaque.tf.points) p.extinction *= 40;
    expect_same(opaque, 0.5, "early termination");
    opaque.integrator.min_transmittance = 0;
    expect_same(opaque, 0.5, "no early termination");
  }
}

TEST(RenderPacket, TransferFunctionEdgeCases) {
  Scene s = calibration_scene(16, 8);
  s.cameras[0].width = 19;
  s.cameras[0].height = 11;
  // Densities exactly on the points: a volume of the points' densities and values between.
  for (std::size_t i = 0; i < s.volume.data.size(); ++i)
    s.volume.data[i] = float(std::vector<double>{0.35, 0.55, 0.8, 0.45, 1.0}[i % 5]);
  // The exact schemes cut their segments at the points: densities on them, and segments whose
  // ends lie on two of them, are their edge cases.
  for (Scheme scheme : {Scheme::midpoint, Scheme::preintegrated, Scheme::exact}) {
    Scene sc = s;
    sc.integrator.scheme = scheme;
    if (scheme == Scheme::exact) sc.model = Model::absorption;
    const std::string name = scheme_name(scheme);
    expect_same(sc, 0.5, name + ", densities on the points");
    Scene two = sc;
    two.tf.points = {{0.2, {1, 0.5, 0.2}, 4}, {0.9, {0.2, 0.4, 1}, 12}};
    expect_same(two, 0.5, name + ", two points");
    Scene one = sc;
    one.tf.points = {{0.5, {0.3, 0.6, 0.9}, 3}};
    expect_same(one, 0.5, name + ", one point");
    Scene opaque = sc;  // early termination at different segments of a packet
    for (TfPoint& p : opaque.tf.points) p.extinction *= 40;
    expect_same(opaque, 0.5, name + ", early termination");
  }
  // The packets' lookup by permutes (a TF of at most 16 rows, kernels/tf.cl) against one ray's
  // search: a step (two points at one density, which is a voxel's), 16 points (the most the
  // columns hold) and 17 (the masked blend instead); tables of 16 and 17 entries likewise.
  Scene step = s;
  step.tf.points = {{0.3, {1, 0.5, 0.2}, 2},
                    {0.45, {0.2, 0.4, 1}, 1},
                    {0.45, {0.9, 0.9, 0.1}, 9},
                    {0.8, {0.5, 0.5, 0.5}, 3}};
  expect_same(step, 0.5, "a step at a voxel's density");
  expect_same(step, 0.5, "a step at a voxel's density, float64", Precision::f64);
  for (int rows : {16, 17}) {
    Scene many = s;
    many.tf.points.clear();
    for (int k = 0; k < rows; ++k)
      many.tf.points.push_back({0.25 + 0.05 * k, {0.05 * k, 1 - 0.05 * k, 0.5}, 1.0 + (k % 5)});
    expect_same(many, 0.5, std::to_string(rows) + " points");
    Scene table = s;
    table.tf.kind = TfKind::table;
    table.tf.range = {0.3, 0.95};
    table.tf.entries.clear();
    for (int k = 0; k < rows; ++k)
      table.tf.entries.push_back({0.05 * k, 0.5, 1 - 0.05 * k, 1.0 + (k % 4)});
    expect_same(table, 0.5, std::to_string(rows) + " table entries");
  }
}

// Volumes 1 and 2 voxels wide, where the float32 trilinear sample's pairs of neighbours meet the
// grid's edge on both sides (kernels/rays.cl, vgather_pair; one voxel wide: plain gathers).
TEST(RenderPacket, NarrowVolumes) {
  for (int nx : {1, 2, 3}) {
    Scene s = calibration_scene(8, 8);
    s.volume = Volume();
    s.volume.nx = nx, s.volume.ny = 6, s.volume.nz = 5;
    for (std::size_t i = 0; i < s.volume.voxel_count(); ++i)
      s.volume.data.push_back(float(0.3 + 0.6 * std::abs(std::sin(0.7 * double(i)))));
    set_default_box(s);
    s.cameras[0].width = 13;
    s.cameras[0].height = 9;
    expect_same(s, 0.4, std::to_string(nx) + " voxels wide");
  }
}

// The four TF kinds, each with σ = 0 over the low densities (the Gaussians: nowhere exactly).
std::vector<std::pair<std::string, TransferFunction>> every_tf_kind() {
  TransferFunction identity;
  identity.kind = TfKind::identity;
  identity.extinction_scale = 9;
  identity.color_scale = 0.8;
  TransferFunction pwl;
  pwl.kind = TfKind::piecewise_linear;
  pwl.points = {{0.1, {0.2, 0.4, 1}, 0}, {0.5, {1, 0.5, 0.25}, 8}, {1.0, {0.2, 0.4, 1}, 14}};
  TransferFunction table;
  table.kind = TfKind::table;
  table.range = {0.2, 1.0};
  table.entries = {{0, 0, 0, 0}, {1, 0, 0, 4}, {0, 1, 0.5, 6}, {0.3, 0.3, 1, 1}, {1, 1, 1, 10}};
  TransferFunction gauss;
  gauss.kind = TfKind::gaussian;
  gauss.gaussians = {{0.3, 0.1, {1, 0.2, 0.1}, 5}, {0.7, 0.2, {0.1, 0.6, 1}, 3}};
  return {{"identity", identity}, {"piecewise_linear", pwl}, {"table", table}, {"gaussian", gauss}};
}

// Whether a scheme takes this model and TF (exact: absorption; both exact schemes: TFs linear in
// density between knots).
bool scheme_supports(Scheme scheme, Model model, const std::string& tf) {
  if (scheme == Scheme::exact && model != Model::absorption) return false;
  return scheme == Scheme::midpoint || scheme == Scheme::trapezoid || tf != "gaussian";
}

struct Case {
  std::string tf;
  Model model;
  Scheme scheme;
  Precision precision;
  EmptySpace skip;
};

// A volume half empty (zeros in its lower z half), bricks of 4 cells, so that packets hold rays
// that skip and rays that sample; two views, 19 × 11 pixels.
void expect_cases_same(const std::vector<Case>& cases) {
  Scene s = calibration_scene(16, 8);
  for (int z = 0; z < 8; ++z)
    for (int i = 0; i < 16 * 16; ++i) s.volume.data[std::size_t(z) * 256 + i] = 0;
  s.cameras[0].width = 19;
  s.cameras[0].height = 11;
  Camera side = s.cameras[0];
  side.eye = {0.3, -1.3, -0.9};
  s.cameras.push_back(side);
  for (const Case& c : cases)
    for (const auto& [tf_name, tf] : every_tf_kind()) {
      if (tf_name != c.tf) continue;
      Scene scene = s;
      scene.tf = tf;
      scene.model = c.model;
      scene.integrator.scheme = c.scheme;
      const std::string what = tf_name + (c.model == Model::absorption ? " absorption " : " ea ") +
                               scheme_name(c.scheme) +
                               (c.precision == Precision::f64 ? " f64" : "") +
                               (c.skip == EmptySpace::on ? " skipping" : "");
      expect_same(scene, 0.5, what, c.precision, c.skip, 4);
    }
}

// Each TF kind once, the models, schemes and skipping in turn, one in float64.
TEST(RenderPacket, EveryTfKindIsTheSame) {
  const Precision f32 = Precision::f32;
  expect_cases_same(
      {{"identity", Model::emission_absorption, Scheme::trapezoid, f32, EmptySpace::on},
       {"piecewise_linear", Model::absorption, Scheme::midpoint, f32, EmptySpace::on},
       {"table", Model::emission_absorption, Scheme::midpoint, f32, EmptySpace::off},
       {"gaussian", Model::absorption, Scheme::trapezoid, f32, EmptySpace::off},
       {"table", Model::emission_absorption, Scheme::trapezoid, Precision::f64, EmptySpace::on},
       {"piecewise_linear", Model::emission_absorption, Scheme::preintegrated, f32, EmptySpace::on},
       {"table", Model::absorption, Scheme::preintegrated, f32, EmptySpace::off},
       {"identity", Model::emission_absorption, Scheme::preintegrated, Precision::f64,
        EmptySpace::off},
       {"piecewise_linear", Model::absorption, Scheme::exact, f32, EmptySpace::on},
       {"table", Model::absorption, Scheme::exact, Precision::f64, EmptySpace::off},
       {"identity", Model::absorption, Scheme::exact, f32, EmptySpace::on}});
}

// The whole matrix (ctest -L extended): every TF kind × model × scheme × precision × skipping.
TEST(RenderPacket, EveryTfKindModelSchemeAndSkippingIsTheSameExtended) {
  std::vector<Case> cases;
  for (const char* tf : {"identity", "piecewise_linear", "table", "gaussian"})
    for (Model model : {Model::emission_absorption, Model::absorption})
      for (Scheme scheme :
           {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact})
        for (Precision precision : {Precision::f32, Precision::f64})
          for (EmptySpace skip : {EmptySpace::off, EmptySpace::on})
            if (scheme_supports(scheme, model, tf))
              cases.push_back({tf, model, scheme, precision, skip});
  expect_cases_same(cases);
}

AdjointGradient gradient_with(const Scene& scene, const Image& target, bool packet) {
  const ScopedEnv env("IVR_PACKET", packet ? "1" : "0");
  AdjointOptions o;
  o.step = 0.5;
  o.tf = o.background = true;
  o.empty_space = EmptySpace::off;
  o.deterministic = true;  // the density gradient's sums in fixed point: comparable bit for bit
  return adjoint(device(), scene, target, o);
}

TEST(RenderPacket, GradientFromThePacketPrimalIsTheSame) {
  Scene s = calibration_scene(16, 8);
  s.cameras[0].width = 21;
  s.cameras[0].height = 13;
  Camera side = s.cameras[0];
  side.eye = {0.2, -1.4, 0.3};
  s.cameras.push_back(side);
  Scene wall = s;  // an opaque wall: behind it C minus the prefix must be exactly the background
  for (int z = 6; z < 9; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) wall.volume.data[(std::size_t(z) * 16 + y) * 16 + x] = 1.f;
  for (TfPoint& p : wall.tf.points) p.extinction *= 50;
  Scene no_stop = wall;
  no_stop.integrator.min_transmittance = 0;
  for (const auto& [scene, what] : {std::pair{s, "calibration"}, std::pair{wall, "opaque wall"},
                                    std::pair{no_stop, "opaque wall, no early termination"}}) {
    Image target = render_at(scene, Precision::f32, 0.5);
    for (std::size_t i = 0; i < target.pixels.size(); ++i)
      target.pixels[i] -= 0.1f + 0.05f * float(i % 4);
    const AdjointGradient a = gradient_with(scene, target, true),
                          b = gradient_with(scene, target, false);
    EXPECT_EQ(a.loss, b.loss) << what;
    EXPECT_EQ(a.samples, b.samples) << what;
    EXPECT_EQ(a.density, b.density) << what;
    EXPECT_EQ(a.background, b.background) << what;
    // The TF rows keep float atomics, whose order varies from run to run: to their rounding.
    ASSERT_EQ(a.tf.size(), b.tf.size()) << what;
    double tf_largest = 0;
    for (double g : b.tf) tf_largest = std::max(tf_largest, std::abs(g));
    for (std::size_t i = 0; i < a.tf.size(); ++i)
      EXPECT_NEAR(a.tf[i], b.tf[i], 1e-6 * tf_largest) << what << " tf " << i;
    double largest = 0;
    for (float g : a.density) largest = std::max(largest, double(std::abs(g)));
    EXPECT_GT(largest, 0) << what;
  }
}

}  // namespace
}  // namespace ivr::test
