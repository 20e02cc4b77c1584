// kernel_config_test.cpp — the typed kernel configuration: preambles and labels derived from it,
// equivalent configurations sharing one program, the kernels' defaults behind the switches it
// leaves out, and no preamble or host–kernel constant written anywhere else.
#include "runtime/kernel_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "runtime/variants.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace ivr::test {
namespace {

std::string text_of(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

KernelConfig adjoint_with(TfKind tf, int rows) {
  RenderVariant v;
  v.tf = tf;
  KernelConfig c = v.config("adjoint.cl", "adjoint");
  return c.set(Switch::tf_rows, rows);
}

TEST(KernelConfig, PreambleAndLabelComeFromTheSwitches) {
  KernelConfig c("array_ops.cl", "sum");
  c.set(Switch::f64, true).set(Switch::acc_f64, true).set(Switch::reduce_size, 256);
  EXPECT_EQ(c.preamble(), "#define IVR_F64 1\n#define IVR_ACC_F64 1\n#define IVR_REDUCE_SIZE 256\n");
  EXPECT_EQ(c.label(), "array_ops.cl [f64 acc=f64 reduce=256]");
  c.with_atomics(AtomicAdd::ext_float_atomics);
  EXPECT_NE(c.preamble().find("#define IVR_FLOAT_ATOMICS 1\n"), std::string::npos);
  EXPECT_EQ(c.preamble().find("IVR_PTX_ATOMICS"), std::string::npos);
  EXPECT_EQ(c.label(), "array_ops.cl [f64 acc=f64 reduce=256 atomics=cl_ext_float_atomics]");
  EXPECT_NE(c.key(), KernelConfig("array_ops.cl", "sum").key());
}

TEST(KernelConfig, EquivalentConfigurationsShareAProgram) {
  // A brick size matters only where bricks are skipped.
  RenderVariant v;
  v.brick_size = 4;
  const KernelConfig a = v.config("render.cl", "render");
  v.brick_size = 16;
  const KernelConfig b = v.config("render.cl", "render");
  EXPECT_EQ(a.key(), b.key());
  v.empty_space = true;
  const KernelConfig c = v.config("render.cl", "render");
  v.brick_size = 4;
  EXPECT_NE(c.key(), v.config("render.cl", "render").key());
  // A switch at the kernels' default of 0 is the same program as the switch left out.
  KernelConfig off = a;
  off.set(Switch::deterministic, false).set(Switch::grad_tf, false);
  EXPECT_EQ(off.key(), a.key());
  // The TF's size: no program of its own except the few Gaussians the adjoint caches per ray.
  EXPECT_EQ(adjoint_with(TfKind::piecewise_linear, 3).key(),
            adjoint_with(TfKind::piecewise_linear, 300).key());
  EXPECT_EQ(adjoint_with(TfKind::table, 2).key(), adjoint_with(TfKind::table, 256).key());
  EXPECT_EQ(adjoint_with(TfKind::gaussian, 5).key(), adjoint_with(TfKind::gaussian, 8).key());
  EXPECT_EQ(adjoint_with(TfKind::gaussian, 9).key(), adjoint_with(TfKind::gaussian, 64).key());
  EXPECT_NE(adjoint_with(TfKind::gaussian, 4).key(), adjoint_with(TfKind::gaussian, 5).key());
  EXPECT_NE(adjoint_with(TfKind::gaussian, 8).key(), adjoint_with(TfKind::gaussian, 9).key());
  EXPECT_NE(adjoint_with(TfKind::gaussian, 3).preamble().find("#define IVR_TF_ROWS 4\n"),
            std::string::npos);
}

// Every switch the preamble leaves out at 0 is read as 0 by every kernel that defaults it, and is
// defaulted somewhere (so that leaving it out means what 0 means).
TEST(KernelConfig, SwitchesLeftOutAtZeroDefaultToZeroInTheKernels) {
  std::map<std::string, std::set<std::string>> defaults;  // macro -> default values
  const std::regex pattern(R"(#ifndef (IVR_\w+)[^\n]*\n#define \1 ([^\s/]+))");
  for (const auto& entry : fs::directory_iterator(IVR_KERNELS_DIR)) {
    const std::string text = text_of(entry.path());
    for (std::sregex_iterator m(text.begin(), text.end(), pattern), end; m != end; ++m)
      defaults[(*m)[1]].insert((*m)[2]);
  }
  const std::vector<std::string> zero = switches_off_by_default();
  EXPECT_GE(zero.size(), 8u);
  for (const std::string& macro : zero) {
    ASSERT_TRUE(defaults.count(macro)) << macro << " has no default in kernels/";
    EXPECT_EQ(defaults[macro], std::set<std::string>{"0"}) << macro;
  }
}

// The preambles, labels and host–kernel constants have one home: no file of lib/ but the kernel
// configuration writes "#define IVR_…" for a kernel, and the layouts the kernels share with the
// host are defined only in kernels/ivr_constants.h.
TEST(KernelConfig, NoPreambleOrSharedConstantIsWrittenTwice) {
  const fs::path root = fs::path(IVR_KERNELS_DIR).parent_path();
  const std::regex define_in_string("\"#define IVR_");
  for (const auto& entry : fs::recursive_directory_iterator(root / "lib")) {
    if (!entry.is_regular_file() || entry.path().stem() == "kernel_config") continue;
    const std::string text = text_of(entry.path());
    EXPECT_FALSE(std::regex_search(text, define_in_string))
        << entry.path() << " writes a kernel #define of its own";
  }
  const std::string shared = text_of(root / "kernels" / "ivr_constants.h");
  const std::regex defined(R"(#define (IVR_\w+) )");
  std::set<std::string> names;
  for (std::sregex_iterator m(shared.begin(), shared.end(), defined), end; m != end; ++m)
    names.insert((*m)[1]);
  EXPECT_TRUE(names.count("IVR_CAMERA_STRIDE") && names.count("IVR_LANE_VOXEL") &&
              names.count("IVR_MAX_LANES"));
  for (const auto& entry : fs::directory_iterator(root / "kernels")) {
    if (entry.path().filename() == "ivr_constants.h") continue;
    const std::string text = text_of(entry.path());
    for (const std::string& name : names)
      EXPECT_EQ(text.find("#define " + name + " "), std::string::npos)
          << entry.path() << " defines " << name << " again";
  }
}

}  // namespace
}  // namespace ivr::test
