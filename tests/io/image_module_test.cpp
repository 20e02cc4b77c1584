// image_module_test.cpp — PNG/EXR/TIFF go through the image module (libivr_image), loaded on
// first use: libivr and the CLI do not link OpenImageIO, and a missing or foreign module is one
// clear error with nothing written.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "ivr/error.hpp"
#include "ivr/render.hpp"
#include "ivr/volume_io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace ivr::test {
namespace {

Image small_image() {
  Image image{1, 3, 5, 4};
  image.pixels.assign(3 * 5 * 4, 0.25f);
  return image;
}

void expect_nothing_written(const std::string& dir) {
  for (const auto& entry : fs::directory_iterator(dir))
    ADD_FAILURE() << "left behind: " << entry.path();
}

TEST(ImageModule, MissingModuleIsOneClearErrorAndNothingWritten) {
  const std::string dir = temp_dir("image_module_missing");
  ScopedEnv env("IVR_IMAGE_MODULE", "/nonexistent/libivr_image.so");
  for (const char* name : {"a.png", "a.exr", "a.tif"}) {
    try {
      save_image_file(dir + "/" + name, small_image());
      ADD_FAILURE() << name << " written without the module";
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::unsupported) << e.what();
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string("cannot write '") + dir + "/" + name + "'"),
                std::string::npos) << what;
      EXPECT_NE(what.find("/nonexistent/libivr_image.so"), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  expect_nothing_written(dir);
  // .npy needs no module.
  save_image_npy(dir + "/a.npy", small_image());
  EXPECT_TRUE(fs::exists(dir + "/a.npy"));
}

TEST(ImageModule, ALibraryThatIsNotTheModuleIsRefused) {
  const std::string dir = temp_dir("image_module_foreign");
  ScopedEnv env("IVR_IMAGE_MODULE", IVR_NO_PLATFORM_SHIM);  // a loadable module, not ours
  try {
    save_image_file(dir + "/a.png", small_image());
    ADD_FAILURE() << "written through a foreign library";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::unsupported);
    EXPECT_NE(std::string(e.what()).find("is not an image module of this ivr"), std::string::npos)
        << e.what();
  }
  expect_nothing_written(dir);
}

#ifdef IVR_TEST_IMAGE_MODULE
TEST(ImageModule, WritesThroughTheModuleOfThisBuild) {
  const std::string dir = temp_dir("image_module_write");
  for (const char* name : {"a.png", "a.exr", "a.tiff"}) {
    save_image_file(dir + "/" + name, small_image());
    EXPECT_GT(fs::file_size(dir + "/" + name), 0u) << name;
  }
}
#endif

// The library and the CLI start without OpenImageIO: neither names it among the libraries it
// needs, directly or through another (ldd lists the whole closure).
TEST(ImageModule, CliAndLibraryDoNotLoadOpenImageIO) {
  const CliResult r = run_program("ldd", IVR_CLI_PATH);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("libivr.so"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("OpenImageIO"), std::string::npos) << r.out;
}

// The CLI finds the module next to libivr; with a missing one, `ivr render -o x.png` fails with
// one line, status non-zero, and no file.
TEST(ImageModule, CliRenderToPngWithAndWithoutTheModule) {
  const std::string dir = temp_dir("image_module_cli");
  const std::vector<float> ones(4 * 4 * 4, 0.5f);
  save_npy(dir + "/vol.npy", {4, 4, 4}, ones.data());
  const std::string scene = write_file(dir + "/scene.json", R"({
      "volume": {"file": "vol.npy"}, "model": "emission_absorption",
      "tf": {"type": "identity", "extinction_scale": 2, "color_scale": 1},
      "cameras": [{"eye": [0, 0, 2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
                   "width": 8, "height": 8}]})");
  // The CLI's own lookup, next to libivr.so (the test binary's variable is not passed on).
  const CliResult ok = run_cli("render " + scene + " -o " + dir + "/ok.png", "IVR_IMAGE_MODULE=");
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_TRUE(fs::exists(dir + "/ok.png"));
  const CliResult bad = run_cli("render " + scene + " -o " + dir + "/bad.png",
                                "IVR_IMAGE_MODULE=/nonexistent/libivr_image.so");
  EXPECT_NE(bad.status, 0);
  EXPECT_EQ(bad.err.rfind("ivr: error: cannot write '", 0), 0u) << bad.err;
  EXPECT_EQ(bad.err.find('\n'), bad.err.size() - 1) << bad.err;
  EXPECT_FALSE(fs::exists(dir + "/bad.png"));
}

}  // namespace
}  // namespace ivr::test
