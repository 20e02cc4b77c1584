// runtime_test.cpp — the OpenCL layer: device listing and selection, readable errors, the
// in-process and on-disk program caches, kernel files and variants.
#include "runtime/runtime.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "runtime/kernel_sources.hpp"
#include "runtime/program_cache.hpp"
#include "test_support.hpp"
#include "runtime/variants.hpp"

namespace fs = std::filesystem;

namespace ivr::test {
namespace {

TEST(Runtime, ListsDevicesWithConsistentIndices) {
  const std::vector<DeviceInfo> devices = list_devices();
  ASSERT_FALSE(devices.empty());
  for (std::size_t i = 0; i < devices.size(); ++i) {
    EXPECT_EQ(devices[i].index, int(i));
    EXPECT_FALSE(devices[i].name.empty());
    EXPECT_TRUE(devices[i].type == "cpu" || devices[i].type == "gpu" ||
                devices[i].type == "accelerator" || devices[i].type == "other");
    EXPECT_GT(devices[i].max_allocation, 0u);
  }
}

// Contexts made on several threads at once, as the first OpenCL calls of the process (each test runs
// in a process of its own): every thread finds the device (PoCL's first listing is not safe to
// run twice at once; the listing is serialised).
TEST(Runtime, ContextsMadeOnSeveralThreadsAtOnce) {
  std::vector<std::string> errors(4);
  auto make = [&errors](std::size_t t) {
    try {
      Device d("");
      if (d.info().name.empty()) errors[t] = "a device without a name";
    } catch (const std::exception& e) {
      errors[t] = e.what();
    }
  };
  // (This thread is one of them. Under AddressSanitizer a thread that initialised the driver and
  // then ends needs use_sigaltstack=0: tests/test_environment.cpp.)
  std::vector<std::thread> threads;
  for (std::size_t t = 1; t < errors.size(); ++t) threads.emplace_back(make, t);
  make(0);
  for (std::thread& t : threads) t.join();
  for (std::size_t t = 0; t < errors.size(); ++t) EXPECT_EQ(errors[t], "") << "thread " << t;
}

TEST(Runtime, SelectsByIndexPairTypeAndName) {
  const DeviceInfo first = list_devices().front();
  EXPECT_EQ(Device("0").info().name, first.name);
  EXPECT_EQ(Device(std::to_string(first.platform_index) + ":" + std::to_string(first.device_index))
                .info()
                .name,
            first.name);
  EXPECT_EQ(Device(first.type).info().type, first.type);
  // Case-insensitive substring of "platform name".
  std::string part = first.name.substr(0, std::min<std::size_t>(6, first.name.size()));
  for (char& c : part) c = char(std::toupper((unsigned char)c));
  EXPECT_EQ(Device(part).info().name, first.name);
}

TEST(Runtime, SelectorFromEnvironmentAndUnknownSelector) {
  {
    ScopedEnv env("IVR_DEVICE", "0");
    EXPECT_EQ(Device().info().index, 0);
  }
  {
    ScopedEnv env("IVR_DEVICE", "no-such-device");
    try {
      Device d;
      FAIL() << "selected " << d.info().name;
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::no_device);
      EXPECT_NE(std::string(e.what()).find("IVR_DEVICE 'no-such-device'"), std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("available: [0]"), std::string::npos) << e.what();
    }
  }
}

TEST(Runtime, ErrorNamesTheCallAndTheCode) {
  EXPECT_STREQ(cl_error_name(-5), "CL_OUT_OF_RESOURCES");
  EXPECT_STREQ(cl_error_name(-11), "CL_BUILD_PROGRAM_FAILURE");
  EXPECT_STREQ(cl_error_name(-9999), "CL_UNKNOWN_ERROR");
  try {
    throw_cl(cl::Error(CL_MEM_OBJECT_ALLOCATION_FAILURE, "clCreateBuffer"),
             "allocating the volume");
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::out_of_memory);
    EXPECT_STREQ(e.what(),
                 "clCreateBuffer failed with CL_MEM_OBJECT_ALLOCATION_FAILURE (-4) while "
                 "allocating the volume");
  }
}

TEST(Runtime, BufferLargerThanTheDeviceAllowsIsOutOfMemory) {
  Device::Impl& dev = device().impl();
  try {
    dev.buffer(CL_MEM_READ_ONLY, dev.info.max_allocation + 1, nullptr, "a test buffer");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::out_of_memory);
    EXPECT_NE(std::string(e.what()).find("a test buffer needs"), std::string::npos);
  }
}

const char* kSource = "__kernel void twice(__global float* x) { x[get_global_id(0)] *= 2.0f; }\n";

// ivr's disk cache serves every platform but PoCL (which caches its builds itself): on the test
// device, which is PoCL, it is exercised through a DeviceInfo that names another platform.
DeviceInfo as_if_not_pocl(DeviceInfo info) {
  info.platform = "NVIDIA CUDA";
  return info;
}

TEST(ProgramCache, MemoryThenDiskThenCompiledAfterCorruption) {
  const std::string dir = temp_dir("program_cache");
  ScopedEnv env("IVR_CACHE_DIR", dir);
  Device::Impl& dev = device().impl();
  const DeviceInfo info = as_if_not_pocl(dev.info);
  const std::string source = std::string(kSource) + "// unique " + dir + "\n";
  ProgramCache cache;
  cache.get(dev.context, dev.device, info, source, "", "twice");
  EXPECT_EQ(cache.last_origin(), "compiled");
  cache.get(dev.context, dev.device, info, source, "", "twice");
  EXPECT_EQ(cache.last_origin(), "memory");
  std::vector<fs::path> files;
  for (const auto& f : fs::directory_iterator(dir)) files.push_back(f.path());
  ASSERT_EQ(files.size(), 1u);

  ProgramCache fresh;  // a new process, in effect
  cl::Program program = fresh.get(dev.context, dev.device, info, source, "", "twice");
  EXPECT_EQ(fresh.last_origin(), "disk");
  // The program from disk works.
  std::vector<float> x{1, 2, 3};
  cl::Buffer buf(dev.context, cl_mem_flags(CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR),
                 std::size_t(12), x.data());
  cl::Kernel k(program, "twice");
  k.setArg(0, buf);
  dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(3));
  dev.queue.enqueueReadBuffer(buf, CL_TRUE, 0, 12, x.data());
  EXPECT_EQ(x, (std::vector<float>{2, 4, 6}));

  std::ofstream(files[0], std::ios::binary | std::ios::trunc) << "not a binary";
  ProgramCache after_corruption;
  after_corruption.get(dev.context, dev.device, info, source, "", "twice");
  EXPECT_EQ(after_corruption.last_origin(), "compiled");

  // Other options make another entry.
  after_corruption.get(dev.context, dev.device, info, source, "-cl-mad-enable", "twice");
  EXPECT_EQ(after_corruption.last_origin(), "compiled");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);
}

// PoCL's programs are never stored in ivr's disk cache, with or without PoCL's own cache
// (program_cache.cpp says why); other platforms' are, whatever POCL_KERNEL_CACHE says.
TEST(ProgramCache, NoBinariesForPocl) {
  const std::string dir = temp_dir("program_cache_pocl");
  ScopedEnv env("IVR_CACHE_DIR", dir);
  Device::Impl& dev = device().impl();
  DeviceInfo pocl = dev.info;
  pocl.platform = "Portable Computing Language";
  const DeviceInfo other = as_if_not_pocl(dev.info);
  const std::string source = std::string(kSource) + "// pocl " + dir + "\n";
  auto origin = [&](const DeviceInfo& info) {
    ProgramCache fresh;  // a new process, in effect
    fresh.get(dev.context, dev.device, info, source, "", "twice");
    return fresh.last_origin();
  };
  for (const char* pocl_cache : {"1", "0"}) {
    ScopedEnv setting("POCL_KERNEL_CACHE", pocl_cache);
    EXPECT_EQ(origin(pocl), "compiled") << pocl_cache;
    EXPECT_EQ(origin(pocl), "compiled") << pocl_cache;
    EXPECT_TRUE(fs::is_empty(dir)) << pocl_cache;
  }
  EXPECT_EQ(origin(other), "compiled");
  EXPECT_EQ(origin(other), "disk");
  ScopedEnv uncached("POCL_KERNEL_CACHE", "0");
  EXPECT_EQ(origin(other), "disk");
}

TEST(ProgramCache, DisabledCacheWritesNothing) {
  const std::string dir = temp_dir("program_cache_off");
  ScopedEnv env("IVR_CACHE_DIR", dir);
  ScopedEnv off("IVR_KERNEL_CACHE", "0");
  EXPECT_EQ(kernel_cache_dir(), "");
  Device::Impl& dev = device().impl();
  ProgramCache cache;
  cache.get(dev.context, dev.device, dev.info, std::string(kSource) + "// off\n", "", "twice");
  EXPECT_EQ(cache.last_origin(), "compiled");
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(ProgramCache, UnwritableCacheFallsBackToCompiling) {
  ScopedEnv env("IVR_CACHE_DIR", "/proc/ivr-cannot-write-here");
  Device::Impl& dev = device().impl();
  ProgramCache cache;
  EXPECT_NO_THROW(
      cache.get(dev.context, dev.device, dev.info, std::string(kSource) + "// ro\n", "", "twice"));
  EXPECT_EQ(cache.last_origin(), "compiled");
}

TEST(ProgramCache, BuildFailureCarriesTheBuildLog) {
  Device::Impl& dev = device().impl();
  ProgramCache cache;
  try {
    cache.get(dev.context, dev.device, dev.info, "__kernel void f() { int x = not_declared_here; }",
              "", "broken.cl");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::build);
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("building kernel broken.cl failed on ", 0), 0u) << msg;
    EXPECT_NE(msg.find("not_declared_here"), std::string::npos) << msg;
  }
}

TEST(KernelSources, IncludesResolvedOnceAndEmbeddedMatchesTheFiles) {
  const std::string text = assemble_kernel("render.cl");
  EXPECT_EQ(text.find("#include"), std::string::npos);
  const std::size_t first = text.find("#ifndef IVR_CONFIG_CL");
  ASSERT_NE(first, std::string::npos);
  EXPECT_EQ(text.find("#ifndef IVR_CONFIG_CL", first + 1), std::string::npos)
      << "config.cl pasted twice";
  for (const auto& [name, embedded] : detail::embedded_kernels()) {
    std::ifstream in(std::string(IVR_KERNELS_DIR) + "/" + name);
    const std::string on_disk((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
    EXPECT_EQ(embedded, on_disk) << name << " is stale in the build";
  }
  EXPECT_THROW(kernel_file("nope.cl"), Error);
}

// Every kernel file is real OpenCL that compiles on its own (default switches), as an offline
// compiler would see it with -I kernels.
TEST(KernelSources, EveryFileCompilesOnItsOwn) {
  Device::Impl& dev = device().impl();
  for (const auto& [name, text] : detail::embedded_kernels()) {
    cl::Program program(dev.context, text);
    try {
      program.build({dev.device}, (std::string("-I ") + IVR_KERNELS_DIR).c_str());
    } catch (const cl::Error&) {
      FAIL() << name << ":\n" << program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(dev.device);
    }
  }
}

// assemble_kernel() pastes each file once, where its first #include stands, whatever the
// preprocessor later keeps: an #include under a condition would hide the file from every later
// includer when the condition is false. So no kernel file includes another under a condition
// (its own include guard aside).
TEST(KernelSources, NoIncludeUnderACondition) {
  for (const auto& [name, text] : detail::embedded_kernels()) {
    std::istringstream lines(text);
    std::string line;
    int depth = 0, number = 0;
    while (std::getline(lines, line)) {
      ++number;
      const std::size_t hash = line.find_first_not_of(" \t");
      if (hash == std::string::npos || line[hash] != '#') continue;
      const std::string directive = line.substr(hash);
      if (directive.rfind("#if", 0) == 0) ++depth;
      if (directive.rfind("#endif", 0) == 0) --depth;
      // Depth 1 is the file's include guard.
      if (directive.rfind("#include", 0) == 0)
        EXPECT_LE(depth, 1) << name << ":" << number << ": " << line;
    }
  }
}

TEST(Variants, PreambleSelectsOnlyWhatTheSceneUses) {
  Scene s = constant_scene(0.5f);
  KernelConfig c = RenderVariant::of(s, s.integrator, Precision::f32).config("render.cl", "render");
  EXPECT_NE(c.preamble().find("#define IVR_MODEL 0\n"), std::string::npos);
  EXPECT_NE(c.preamble().find("#define IVR_EARLY_TERMINATION 0\n"), std::string::npos);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::gaussian;
  s.integrator.min_transmittance = 1e-3;
  c = RenderVariant::of(s, s.integrator, Precision::f64).config("render.cl", "render");
  EXPECT_NE(c.preamble().find("#define IVR_MODEL 1\n"), std::string::npos);
  EXPECT_NE(c.preamble().find("#define IVR_TF 3\n"), std::string::npos);
  EXPECT_NE(c.preamble().find("#define IVR_F64 1\n"), std::string::npos);
  EXPECT_EQ(c.label(),
            "render.cl [model=emission_absorption tf=gaussian scheme=midpoint f64 ert=on "
            "empty_space=off]");
  // The render reports the variant it ran (on CPUs in packets of 16 rays in vector lanes).
  Scene a = constant_scene(0.5f);
  RenderStats stats;
  render(device(), a, {}, &stats);
  EXPECT_EQ(stats.variant,
            std::string("render.cl [model=absorption tf=identity scheme=midpoint f32 ert=off "
                        "empty_space=off") +
                (device().info().type == "cpu" ? " packet=16]" : "]"));
}

}  // namespace
}  // namespace ivr::test

namespace ivr::test {
namespace {

TEST(Runtime, Float64OnADeviceWithoutFp64IsUnsupported) {
  // PoCL has fp64, so pretend it has not: the check must happen before any kernel is built.
  DeviceInfo& info = device().impl().info;
  const bool had = info.fp64;
  info.fp64 = false;
  try {
    render(device(), constant_scene(0.5f), {Precision::f64});
    ADD_FAILURE() << "rendered in f64 on a device without fp64";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::unsupported);
    EXPECT_NE(std::string(e.what()).find("no float64 support"), std::string::npos) << e.what();
  }
  info.fp64 = had;
}

}  // namespace
}  // namespace ivr::test
