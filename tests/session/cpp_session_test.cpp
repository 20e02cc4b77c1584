// cpp_session_test.cpp — ivr/ivr_session.hpp, the header-only C++ RAII layer over C API sessions.
#include <gtest/gtest.h>

#include "capi/api_test_support.hpp"
#include "capi/c_api_session_support.hpp"

namespace ivr::test {
namespace {

TEST(CppSession, RenderGradientAndStepEqualTheOneShotCalls) {
  const std::vector<float> volume = test_volume(16, 18, 20, 1);
  api::Context ctx;
  api::Scene scene = ctx.scene_from_json(SceneParts{}.json());
  scene.set_volume(volume, {16, 18, 20});
  api::Session session(ctx, scene);
  EXPECT_EQ(session.image_shape(), (std::vector<int64_t>{2, 16, 20, 4}));
  EXPECT_EQ(session.volume_shape(), (std::vector<int64_t>{16, 18, 20}));
  const api::DeviceArray image = session.render();
  EXPECT_EQ(image.shape(), (std::vector<int64_t>{2, 16, 20, 4}));
  EXPECT_EQ(image.dtype(), api::DType::f32);
  const api::Array<float> want = ctx.render(scene);
  EXPECT_TRUE(image.download().values == want.values);

  std::vector<float> target(want.values);
  for (size_t i = 0; i < target.size(); ++i) target[i] = 0.85f * target[i] + 0.01f;
  api::DeviceArray target_array(ctx, {2, 16, 20, 4});
  target_array.upload(target);
  session.set_target(target_array);
  const api::SessionGradient g = session.gradient("density,background", api::Mode::adjoint);
  EXPECT_EQ(g.mode, api::Mode::adjoint);
  api::GradientOptions o;
  o.wrt = "density,background";
  o.mode = api::Mode::adjoint;
  const api::Result r = ctx.gradient(scene, target, o);
  EXPECT_NEAR(g.loss.item(), r.loss(), 1e-6 * r.loss());
  EXPECT_EQ(g["density"].shape(), (std::vector<int64_t>{16, 18, 20}));
  expect_close(g["density"].download_f64().values, r.array("density").values, 1e-5, 1e-5,
               "density");
  expect_close(g["background"].download_f64().values, r.array("background").values, 1e-5, 1e-5,
               "background");
  expect_throw([&] { (void)g["tf"]; }, IVR_ERROR_INVALID_ARGUMENT, "no group 'tf'");
  // voxels:LIST is named "voxels"; a target passed in rather than the session's.
  const std::string voxels = "voxels:" + std::to_string(kCentre) + "," +
                             std::to_string(kCentre + 1) + "-" + std::to_string(kCentre + 2);
  const api::SessionGradient f =
      session.gradient("tf," + voxels, api::Mode::forward, api::Loss::l1, false, &target_array);
  ASSERT_EQ(f.groups.size(), 2u);
  EXPECT_EQ(f.groups[0].first, "tf");
  EXPECT_EQ(f.groups[1].first, "voxels");
  EXPECT_EQ(f["voxels"].shape(), (std::vector<int64_t>{3}));

  // Adam steps lower the loss; the volume view stays >= 0.
  api::DensityOptimizer adam(session, IVR_OPTIMIZER_ADAM, 0.01);
  double first = 0, last = 0;
  for (int k = 0; k < 10; ++k) {
    const api::SessionGradient step = session.gradient("density", api::Mode::adjoint);
    (k == 0 ? first : last) = step.loss.item();
    session.step(adam, step["density"]);
  }
  EXPECT_LT(last, first);
  const api::Array<float> stepped = session.volume().download();
  EXPECT_EQ(stepped.shape, (std::vector<int64_t>{16, 18, 20}));
  EXPECT_GE(*std::min_element(stepped.values.begin(), stepped.values.end()), 0.f);
  EXPECT_NE(stepped.values, volume);
}

TEST(CppSession, ErrorsThrowTheStatusAndMessage) {
  api::Context ctx;
  api::Scene scene = ctx.scene_from_json(SceneParts{}.json());
  scene.set_volume(test_volume(16, 18, 20, 1), {16, 18, 20});
  api::Session session(ctx, scene);
  std::vector<float> bad = test_volume(16, 18, 20, 1);
  bad[(3 * 18 + 2) * 20 + 1] = -1.f;
  expect_throw(
      [&] {
        session.set_volume(bad, {16, 18, 20});
      },
      IVR_ERROR_INVALID_ARGUMENT, "(x, y, z) = (1, 2, 3)");
  expect_throw([&] { session.set_volume(bad, {16, 18}); }, IVR_ERROR_INVALID_ARGUMENT, "3-d shape");
  expect_throw([&] { session.gradient("density"); }, IVR_ERROR_INVALID_ARGUMENT, "no target");
  expect_throw([&] { session.set_cameras_json("[{"); }, IVR_ERROR_IO,
               "ivr_session_set_cameras_json");
  expect_throw([&] { session.set_integrator_json(R"({"step": 0})"); }, IVR_ERROR_INVALID_ARGUMENT,
               "integrator.step");
  expect_throw(
      [&] {
        api::DeviceArray(ctx, {1, 1, 1, 1, 1, 1, 1, 1, 1});
      },
      IVR_ERROR_INVALID_ARGUMENT, "rank 9");
  api::DeviceArray small(ctx, {3});
  expect_throw(
      [&] {
        small.upload(std::vector<float>{1, 2});
      },
      IVR_ERROR_INVALID_ARGUMENT, "2 values for an array of 3");
  api::Context other;
  const api::DeviceArray foreign(other, {16, 18, 20});
  expect_throw([&] { session.set_volume(foreign); }, IVR_ERROR_WRONG_CONTEXT, "another context");
  api::DensityOptimizer adam(session, IVR_OPTIMIZER_ADAM, 0.01);
  expect_throw([&] { session.step(adam, small); }, IVR_ERROR_INVALID_ARGUMENT, "gradient");
  expect_throw([&] { api::DensityOptimizer(session, IVR_OPTIMIZER_LBFGS, 0.01); },
               IVR_ERROR_INVALID_ARGUMENT, "ivr_density_optimizer_create");
  const api::Session empty(static_cast<ivr_session*>(nullptr));
  expect_throw([&] { api::Session(empty).render(); }, IVR_ERROR_NULL_POINTER, "ivr_session_render");
  // The session still renders what it rendered before the failures.
  EXPECT_TRUE(session.render().download().values == ctx.render(scene).values);
}

}  // namespace
}  // namespace ivr::test
