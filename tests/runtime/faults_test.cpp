// faults_test.cpp — faults a long-running user meets: a device allocation failing in the middle
// of an operation (injected: lib/runtime/runtime.hpp inject_allocation_failure) must release everything
// and leave the device and a session usable; many operations in one process keep device memory
// and the resident set flat.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <fstream>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
#define IVR_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define IVR_TEST_ASAN 1
#endif
#endif
#ifdef IVR_TEST_ASAN
// Declared here: GCC ships the runtime but not <sanitizer/allocator_interface.h>.
extern "C" std::size_t __sanitizer_get_current_allocated_bytes(void);
#endif

#include "ivr/core.hpp"
#include "ivr/session.hpp"
#include "runtime/runtime.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A small emission–absorption scene with structure, and a target it does not match.
Scene fault_scene() {
  Scene s = constant_scene(0.5f, 6, 8);
  for (std::size_t i = 0; i < s.volume.data.size(); ++i)
    s.volume.data[i] = float(0.3 + 0.2 * std::sin(0.9 * double(i)));
  s.cameras[0].eye = {0.4, 0.3, 2};
  return s;
}

Image target_of(const Scene& s) {
  Image t;
  t.views = 1, t.height = s.cameras[0].height, t.width = s.cameras[0].width, t.channels = 1;
  t.pixels.assign(std::size_t(t.height) * t.width, 0.2f);
  return t;
}

double max_relative(const std::vector<float>& a, const std::vector<float>& b) {
  double largest = 0, diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    largest = std::max(largest, double(std::abs(b[i])));
    diff = std::max(diff, double(std::abs(a[i] - b[i])));
  }
  return diff / std::max(largest, 1e-30);
}

// The host memory a leak would grow: the resident set; under AddressSanitizer the bytes its
// allocator has live, because its quarantine deliberately keeps freed blocks resident (up to
// 256 MiB: the resident set grew 25-29 MiB over 360 calls whose live bytes stayed flat).
std::int64_t host_bytes_in_use() {
#ifdef IVR_TEST_ASAN
  return std::int64_t(__sanitizer_get_current_allocated_bytes());
#else
  std::ifstream statm("/proc/self/statm");
  std::int64_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * ::sysconf(_SC_PAGESIZE);
#endif
}

class Faults : public ::testing::Test {
 protected:
  void TearDown() override { inject_allocation_failure(0); }
};

// Every allocation of a one-shot gradient fails in turn: each failure is a clear out_of_memory
// error, no buffer outlives it, and the next call on the same device gives the same gradient.
TEST_F(Faults, AllocationFailureAtEveryPointReleasesEverything) {
  Device dev(std::to_string(device().info().index));  // its own counts
  const Scene scene = fault_scene();
  const Image target = target_of(scene);
  AdjointOptions o;
  o.deterministic = true;
  const AdjointGradient reference = adjoint(dev, scene, target, o);
  dev.impl().queue.finish();
  const std::int64_t baseline = dev.impl().live->settle();
  int failures = 0;
  for (long n = 1; n < 200; ++n) {
    inject_allocation_failure(n);
    bool failed = false;
    try {
      adjoint(dev, scene, target, o);
    } catch (const Error& e) {
      failed = true;
      EXPECT_EQ(e.status(), Status::out_of_memory) << e.what();
      EXPECT_TRUE(has(e.what(), "allocating")) << e.what();
    }
    inject_allocation_failure(0);
    dev.impl().queue.finish();
    // A leak never comes down to the baseline; a late driver callback does, within 2 s.
    EXPECT_EQ(dev.impl().live->settle(baseline, 2000), baseline) << "after a failure at allocation " << n;
    if (!failed) break;
    ++failures;
  }
  EXPECT_GE(failures, 3) << "the gradient allocates more than that: was each point reached?";
  const AdjointGradient again = adjoint(dev, scene, target, o);
  EXPECT_EQ(again.density, reference.density);
  EXPECT_EQ(again.loss, reference.loss);
}

// A session whose gradient fails for want of memory part-way keeps its scene: the next gradient
// equals the one-shot reference.
TEST_F(Faults, SessionSurvivesAnAllocationFailure) {
  const Scene scene = fault_scene();
  const Image target = target_of(scene);
  AdjointOptions o;
  o.deterministic = true;
  const AdjointGradient reference = adjoint(device(), scene, target, o);
  Session session(device(), scene);
  DeviceArray t(device(), {1, target.height, target.width, 1}, DType::f32);
  t.upload(target.pixels.data(), target.pixels.size());
  GradientRequest request;
  request.deterministic = true;
  int failures = 0;
  for (long n = 1; n < 50; ++n) {
    inject_allocation_failure(n);
    try {
      session.gradient(t, request);
      inject_allocation_failure(0);
      break;
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::out_of_memory) << e.what();
      ++failures;
    }
    inject_allocation_failure(0);
    const SessionGradient g = session.gradient(t, request);
    EXPECT_LE(max_relative(g["density"].to_floats(), reference.density), 1e-6)
        << "after a failure at allocation " << n;
  }
  EXPECT_GE(failures, 1);
}

// Many render + gradient calls, one-shot and in a session: device bytes return to where they
// were and host memory (host_bytes_in_use) does not grow with the count (glibc keeps freed pages,
// so growth is measured between two late points, not from the start).
void many_operations(int count) {
  Device dev(std::to_string(device().info().index));
  const Scene scene = fault_scene();
  const Image target = target_of(scene);
  Session session(dev, scene);
  DeviceArray t(dev, {1, target.height, target.width, 1}, DType::f32);
  t.upload(target.pixels.data(), target.pixels.size());
  dev.impl().queue.finish();
  const std::int64_t session_bytes = dev.impl().live->settle();
  std::int64_t rss_at_tenth = 0;
  for (int i = 0; i < count; ++i) {
    if (i % 2 == 0) {
      render(dev, scene, {});
      adjoint(dev, scene, target, {});
    } else {
      session.render().wait();
      session.gradient(t)["density"].wait();
    }
    if (i == count / 10) {
      dev.impl().queue.finish();
      rss_at_tenth = host_bytes_in_use();
    }
  }
  dev.impl().queue.finish();
  // The session keeps its scratch (image, gradients) between calls: bounded, not per call.
  const std::int64_t after = dev.impl().live->settle(session_bytes, 2000);
  EXPECT_LE(after - session_bytes, std::int64_t(1) << 20) << "device bytes grew";
  const std::int64_t growth = host_bytes_in_use() - rss_at_tenth;
  EXPECT_LE(growth, std::int64_t(16) << 20)
      << "host memory in use grew by " << growth << " bytes over " << count * 9 / 10 << " calls";
  std::cout << "[ MEMORY   ] " << count << " render+gradient pairs: device bytes " << session_bytes
            << " -> " << after << ", host memory growth after the first tenth " << growth
            << " bytes\n";
}

TEST_F(Faults, ManyOperationsKeepMemoryFlat) { many_operations(400); }

// The figure: 10,000 calls (`ctest -L extended -R ManyOperations`).
TEST_F(Faults, ManyOperationsKeepMemoryFlatExtended) { many_operations(10000); }

}  // namespace
}  // namespace ivr::test
