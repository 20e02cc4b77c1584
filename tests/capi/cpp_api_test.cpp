// cpp_api_test.cpp — the header-only C++ API (ivr/ivr.hpp) over the C API: results equal to the
// core's, handles shared by copy and kept alive by their reference count, errors thrown as
// ivr::api::Exception with the status and message, and the README's C and C++ snippets being
// the examples the suite builds and runs.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "adjoint/adjoint_support.hpp"
#include "capi/api_test_support.hpp"
#include "ivr/ivr.hpp"

namespace ivr::test {
namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  return std::string(std::istreambuf_iterator<char>(in), {});
}

const std::string kSceneText = read_text(std::string(IVR_TESTS_DIR) + "/data/binding_scene.json");

std::vector<float> test_volume() {
  std::vector<float> v(4 * 5 * 6);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(0.3 + 0.2 * std::cos(1.3 * double(i)));
  return v;
}

// The core scene the wrapper's calls should amount to.
Scene core_scene(const std::vector<float>& volume) {
  Scene s = parse_scene(std::string(kSceneText).insert(1, R"("volume": {"synthetic": "sphere",
      "dims": [2, 2, 2]}, )"),
                        ".");
  s.volume.nx = 6, s.volume.ny = 5, s.volume.nz = 4;
  s.volume.data = volume;
  set_default_box(s);
  return s;
}


TEST(CppApi, RenderGradientAndJacobianEqualTheCore) {
  const std::vector<float> volume = test_volume();
  api::Context ctx;
  api::Scene scene = ctx.scene_from_json(kSceneText);
  scene.set_volume(volume, {4, 5, 6});
  EXPECT_EQ(scene.volume_shape(), (std::vector<int64_t>{4, 5, 6}));
  const Scene s = core_scene(volume);

  const api::Array<float> image = ctx.render(scene);
  EXPECT_EQ(image.shape, (std::vector<int64_t>{1, 5, 6, 4}));
  EXPECT_EQ(image.values, render(device(), s, {Precision::f32}).pixels);

  const Image target = perturbed_target(s);
  api::GradientOptions o;
  o.wrt = "density,background";
  o.mode = api::Mode::adjoint;
  o.loss = api::Loss::l1;
  o.precision = api::Precision::f64;
  const api::Result g = ctx.gradient(scene, target.pixels, o);
  GradientOptions core;
  core.mode = Mode::adjoint;
  core.loss = Loss::l1;
  core.precision = Precision::f64;
  const Gradient d = gradient(device(), s, target, {"density", "background"}, core);
  EXPECT_DOUBLE_EQ(g.loss(), d.loss);
  EXPECT_EQ(g.mode(), api::Mode::adjoint);
  EXPECT_GE(g.seconds(), 0.0);
  const std::vector<api::NamedArray> arrays = g.arrays();
  ASSERT_EQ(arrays.size(), d.groups.size());
  for (std::size_t i = 0; i < arrays.size(); ++i) {
    EXPECT_EQ(arrays[i].name, d.groups[i].name);
    EXPECT_EQ(arrays[i].array.values, d.groups[i].values) << arrays[i].name;
  }
  EXPECT_EQ(g.array("density").shape, (std::vector<int64_t>{4, 5, 6}));
  EXPECT_DOUBLE_EQ(api::image_loss(image.values, target.pixels, api::Loss::l1),
                   image_loss(render(device(), s, {Precision::f32}), target, Loss::l1));

  const api::Array<double> j = ctx.jacobian(scene, "background").array("jacobian");
  EXPECT_EQ(j.shape, (std::vector<int64_t>{1, 5, 6, 4, 3}));
}

TEST(CppApi, VolumeAndTransferFunctionHandles) {
  api::Context ctx;
  const api::Volume ml =
      ctx.volume_from_json(R"({"synthetic": "marschner_lobb", "dims": [5, 6, 7]})");
  EXPECT_EQ(ml.shape(), (std::vector<int64_t>{7, 6, 5}));
  EXPECT_EQ(ml.data().values, synthetic_volume("marschner_lobb", 5, 6, 7).data);
  const std::vector<float> volume = test_volume();
  api::Scene scene = ctx.scene_from_json(kSceneText);
  scene.set_volume(ctx.volume(volume, {4, 5, 6}));
  const char* tf = R"({"type": "table", "range": [0, 1], "entries": [[0, 0, 0, 0], [1, 1, 1, 5]]})";
  scene.set_tf(ctx.tf_from_json(tf));
  Scene s = core_scene(volume);
  s.tf = parse_tf(tf);
  EXPECT_EQ(ctx.render(scene).values, render(device(), s, {Precision::f32}).pixels);
  expect_throw([&] { ctx.volume(volume, {4, 5}); }, IVR_ERROR_INVALID_ARGUMENT, "3-d shape");
  expect_throw([&] { ctx.tf_from_json(R"({"type": "table"})"); }, IVR_ERROR_INVALID_ARGUMENT,
               "entries");
  api::Context other;
  expect_throw(
      [&] {
        scene.set_volume(other.volume(volume, {4, 5, 6}));
      },
      IVR_ERROR_WRONG_CONTEXT, "another context");
}

TEST(CppApi, CopiesShareTheHandleAndKeepItAlive) {
  api::Scene copy;
  {
    api::Context ctx;
    api::Scene scene = ctx.scene_from_json(kSceneText);
    scene.set_volume(test_volume(), {4, 5, 6});
    copy = scene;                         // retains
    api::Scene moved = std::move(scene);  // no retain; `scene` is empty
    EXPECT_FALSE(scene);
    EXPECT_EQ(moved.get(), copy.get());
  }  // the context and the other references go; the scene holds its context
  EXPECT_EQ(copy.image_shape(), (std::vector<int64_t>{1, 5, 6, 4}));
  EXPECT_EQ(copy.volume_shape(), (std::vector<int64_t>{4, 5, 6}));
}

TEST(CppApi, ErrorsThrowTheStatusAndMessage) {
  expect_throw([] { api::Context("no-such-device-name"); }, IVR_ERROR_NO_DEVICE,
               "ivr_context_create");
  api::Context ctx;
  expect_throw([&] { ctx.scene_from_json("{ not json"); }, IVR_ERROR_IO, "ivr_scene_from_json");
  expect_throw([&] { ctx.load_scene("/nonexistent/scene.json"); }, IVR_ERROR_IO,
               "/nonexistent/scene.json");
  api::Scene scene = ctx.scene_from_json(kSceneText);
  expect_throw([&] { ctx.render(scene); }, IVR_ERROR_INVALID_ARGUMENT, "no volume");
  expect_throw(
      [&] {
        scene.set_volume(std::vector<float>(10), {4, 5, 6});
      },
      IVR_ERROR_INVALID_ARGUMENT, "10 values");
  expect_throw(
      [&] {
        scene.set_volume(test_volume().data(), {4, 5});
      },
      IVR_ERROR_INVALID_ARGUMENT, "2 dimensions");
  scene.set_volume(test_volume(), {4, 5, 6});
  api::GradientOptions o;
  o.wrt = "density,nonsense";
  expect_throw([&] { ctx.gradient(scene, std::vector<float>(120, 0.f), o); },
               IVR_ERROR_INVALID_ARGUMENT, "nonsense");
  o.wrt = "density";
  expect_throw([&] { ctx.gradient(scene, std::vector<float>(7, 0.f), o); },
               IVR_ERROR_INVALID_ARGUMENT, "ivr_gradient");
  const api::Result r = ctx.jacobian(scene, "background");
  expect_throw([&] { r.array("density"); }, IVR_ERROR_INVALID_ARGUMENT, "no array named");
  expect_throw([] { api::image_loss({1, 2}, {1}); }, IVR_ERROR_INVALID_ARGUMENT, "image_loss");
  const api::Scene empty;
  expect_throw([&] { empty.image_shape(); }, IVR_ERROR_NULL_POINTER, "ivr_scene_image_shape");
}

TEST(CppApi, DevicesJsonIsTheCoreList) {
  EXPECT_EQ(api::Context::devices_json(), devices_json());
  EXPECT_EQ(api::version(), IVR_VERSION);
}

// The lines of `text` between the markers "README: <tag> begin" and "... end", each trimmed.
std::vector<std::string> trimmed_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    const std::size_t a = line.find_first_not_of(' ');
    line = a == std::string::npos ? "" : line.substr(a);
    if (!line.empty()) lines.push_back(line);
    start = end + 1;
  }
  return lines;
}

std::string between(const std::string& text, const std::string& from, const std::string& to) {
  const std::size_t a = text.find(from);
  const std::size_t b = a == std::string::npos ? a : text.find(to, a + from.size());
  if (b == std::string::npos) return {};
  const std::size_t line = text.find('\n', a);
  return text.substr(line + 1, text.rfind('\n', b) - line);
}

// The README's C and C++ snippets are, line for line, parts of the examples the suite builds
// and runs (example_c_render, example_cpp_render), so they compile and work as written.
TEST(CppApi, ReadmeSnippetsAreTheRunExamples) {
  const std::string root = std::string(IVR_TESTS_DIR) + "/..";
  const std::string readme = read_text(root + "/README.md");
  const std::string section = between(readme, "## Use it from C, C++, Python", "**Python**");
  ASSERT_FALSE(section.empty()) << "README has no 'Use it from C, C++, Python' section";
  const struct {
    const char* fence;
    const char* example;
    const char* tag;
  } snippets[] = {{"```c\n", "/examples/c/render.c", "C"},
                  {"```cpp\n", "/examples/cpp/render.cpp", "C++"}};
  for (const auto& s : snippets) {
    const std::size_t at = section.find(s.fence);
    ASSERT_NE(at, std::string::npos) << s.tag << " snippet";
    const std::string code =
        section.substr(at + std::string(s.fence).size(),
                       section.find("```", at + 3) - at - std::string(s.fence).size());
    const std::string example = read_text(root + s.example);
    const std::string marked = between(example, std::string("README: ") + s.tag + " begin",
                                       std::string("README: ") + s.tag + " end");
    EXPECT_EQ(trimmed_lines(code), trimmed_lines(marked)) << s.example;
  }
}

}  // namespace
}  // namespace ivr::test
