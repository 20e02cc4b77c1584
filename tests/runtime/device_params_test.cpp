// device_params_test.cpp — the launch database's lookup (the most specific row wins, wherever it
// stands), the compiled rows (lib/runtime/device_params_db.inc), $IVR_LOCAL_SIZE, and the tuner's probe in
// the launch layer.
#include "runtime/device_params.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <tuple>

#include "runtime/launch.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

DeviceInfo fake(const std::string& vendor, const std::string& name) {
  DeviceInfo d;
  d.vendor = vendor;
  d.name = name;
  d.type = "gpu";
  return d;
}

// Least specific first, so that no test passes by file order alone.
const std::vector<DatabaseRow> kTable = {
    {"", "", "", 0, 0},
    {"render", "", "", 64, 1},
    {"", "NVIDIA", "", 32, 4},
    {"render", "NVIDIA", "", 16, 8},
    {"", "NVIDIA", "A100", 8, 8},
    {"render", "NVIDIA", "A100", 32, 8},
    {"render", "NVIDIA", "A100-SXM4", 16, 16},
};

TEST(DeviceParams, DeviceRowBeatsVendorRowBeatsDefault) {
  const LaunchParams p =
      lookup_launch_params(kTable, fake("NVIDIA Corporation", "NVIDIA A100-PCIE"), "render");
  EXPECT_EQ(p.local_x, 32);
  EXPECT_EQ(p.local_y, 8);
  EXPECT_EQ(p.source, "render/NVIDIA/A100");
  const LaunchParams v =
      lookup_launch_params(kTable, fake("NVIDIA Corporation", "NVIDIA H100"), "render");
  EXPECT_EQ(v.local_x, 16);
  EXPECT_EQ(v.local_y, 8);
  EXPECT_EQ(v.source, "render/NVIDIA/*");
  const LaunchParams d =
      lookup_launch_params(kTable, fake("Advanced Micro Devices", "gfx90a"), "adjoint");
  EXPECT_EQ(d.local_x, 0);
  EXPECT_EQ(d.local_y, 0);
  EXPECT_EQ(d.source, "default");
}

TEST(DeviceParams, KernelRowBeatsEveryKernelRowOfTheSameLevel) {
  // The vendor's every-kernel row for another kernel; the kernel's own rows beyond the vendor.
  EXPECT_EQ(lookup_launch_params(kTable, fake("NVIDIA", "H100"), "adjoint").source, "*/NVIDIA/*");
  EXPECT_EQ(lookup_launch_params(kTable, fake("NVIDIA", "A100"), "adjoint").source,
            "*/NVIDIA/A100");
  // Another vendor: the kernel's every-device row beats the default.
  const LaunchParams p = lookup_launch_params(kTable, fake("Intel", "Arc A770"), "render");
  EXPECT_EQ(p.local_x, 64);
  EXPECT_EQ(p.source, "render/*/*");
}

TEST(DeviceParams, LongerDeviceNameWinsAndOrderDoesNotMatter) {
  EXPECT_EQ(lookup_launch_params(kTable, fake("NVIDIA", "NVIDIA A100-SXM4-80GB"), "render").source,
            "render/NVIDIA/A100-SXM4");
  std::vector<DatabaseRow> reversed(kTable.rbegin(), kTable.rend());
  for (const char* name : {"NVIDIA A100-SXM4-80GB", "NVIDIA A100", "H100"})
    for (const char* kernel : {"render", "adjoint"}) {
      const LaunchParams a = lookup_launch_params(kTable, fake("NVIDIA", name), kernel);
      const LaunchParams b = lookup_launch_params(reversed, fake("NVIDIA", name), kernel);
      EXPECT_EQ(a.source, b.source) << name << " " << kernel;
      EXPECT_EQ(a.local_x, b.local_x) << name << " " << kernel;
    }
}

TEST(DeviceParams, NoMatchingRowLeavesTheDriverChoice) {
  const std::vector<DatabaseRow> table = {{"render", "NVIDIA", "", 16, 8}};
  const LaunchParams p = lookup_launch_params(table, fake("Intel", "Arc"), "render");
  EXPECT_EQ(p.local_x, 0);
  EXPECT_EQ(p.source, "none");
}

TEST(DeviceParams, CompiledDatabaseHasADefaultAndNoDuplicateRows) {
  const std::vector<DatabaseRow>& rows = launch_database();
  std::set<std::tuple<std::string, std::string, std::string>> keys;
  bool has_default = false;
  const std::vector<std::string> kernels = tune_kernels();
  for (const DatabaseRow& r : rows) {
    EXPECT_TRUE(keys.insert({r.kernel, r.vendor, r.device}).second)
        << "two rows for {" << r.kernel << ", " << r.vendor << ", " << r.device << "}";
    has_default |= !*r.kernel && !*r.vendor && !*r.device;
    if (*r.kernel)
      EXPECT_NE(std::find(kernels.begin(), kernels.end(), r.kernel), kernels.end())
          << "unknown kernel " << r.kernel;
    EXPECT_TRUE((r.local_x == 0 && r.local_y == 0) || (r.local_x > 0 && r.local_y > 0))
        << r.kernel << " " << r.local_x << "x" << r.local_y;
  }
  EXPECT_TRUE(has_default);
  // An unknown device falls back to the default row.
  EXPECT_EQ(launch_params(fake("No Such Vendor", "No Such Device"), "render").source, "default");
}

TEST(DeviceParams, EnvironmentOverridesAndIsChecked) {
  {
    const ScopedEnv env("IVR_LOCAL_SIZE", "16x4");
    const LaunchParams p = launch_params(fake("NVIDIA", "A100"), "render");
    EXPECT_EQ(p.local_x, 16);
    EXPECT_EQ(p.local_y, 4);
    EXPECT_EQ(p.source, "env");
  }
  const ScopedEnv env("IVR_LOCAL_SIZE", "16by4");
  try {
    launch_params(fake("NVIDIA", "A100"), "render");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument);
    EXPECT_TRUE(has(e.what(), "16by4")) << e.what();
  }
}

// The tuner's probe shapes its kernel on this thread only while installed, keeps renders off the
// packet kernel when asked, and records every pixel launch.
TEST(DeviceParams, TuningProbeShapesAndRecordsLaunches) {
  Session session(device(), calibration_scene(8, 16));
  TuningProbe probe;
  probe.kernel = "render";
  probe.local_x = 16;
  probe.local_y = 2;
  probe.packet = false;
  {
    const ScopedTuningProbe scope(probe);
    EXPECT_EQ(tuning_probe(), &probe);
    session.render().wait();
  }
  EXPECT_EQ(tuning_probe(), nullptr);
  ASSERT_EQ(probe.launches.size(), 1u);
  const TuningProbe::Launch& l = probe.launches[0];
  EXPECT_EQ(l.shape.tuning, "render");
  EXPECT_EQ(l.shape.group_x, 16);
  EXPECT_EQ(l.shape.group_y, 2);
  EXPECT_GT(l.shape.kernel_max_group, 0u);
  EXPECT_GE(event_seconds(l.event), 0.0);
  session.render().wait();  // uninstalled: nothing more recorded
  EXPECT_EQ(probe.launches.size(), 1u);
}

}  // namespace
}  // namespace ivr::test
