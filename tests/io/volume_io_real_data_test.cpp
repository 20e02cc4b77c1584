// volume_io_real_data_test.cpp — the real volumes in ../shared/data read as the data README says.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "io/files.hpp"
#include "ivr/volume_io.hpp"
#include "io/volume_test_support.hpp"

namespace fs = std::filesystem;
using ivr::VolumeSource;
using ivr::test::src;

namespace {

std::vector<unsigned char> read_bytes(const std::string& path) {
  return ivr::read_binary_file(path, "test data");
}

class RealVolumeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::is_directory(IVR_SHARED_DATA_DIR)) GTEST_SKIP() << "no " << IVR_SHARED_DATA_DIR;
  }
  static std::string file(const std::string& name) {
    return (fs::path(IVR_SHARED_DATA_DIR) / name).string();
  }
  // Compares v with densities computed here from the file's bytes: count, min, max, mean, order.
  static void check(const ivr::Volume& v, int x, int y, int z, const std::vector<double>& expect) {
    ASSERT_EQ(v.nx, x);
    ASSERT_EQ(v.ny, y);
    ASSERT_EQ(v.nz, z);
    ASSERT_EQ(v.data.size(), expect.size());
    double sum = 0, want_sum = 0;
    for (std::size_t i = 0; i < expect.size(); ++i) {
      ASSERT_FLOAT_EQ(v.data[i], float(expect[i])) << "voxel " << i;
      sum += v.data[i];
      want_sum += expect[i];
    }
    EXPECT_NEAR(sum / expect.size(), want_sum / expect.size(), 1e-6);
    EXPECT_EQ(*std::min_element(v.data.begin(), v.data.end()),
              float(*std::min_element(expect.begin(), expect.end())));
    EXPECT_EQ(*std::max_element(v.data.begin(), v.data.end()),
              float(*std::max_element(expect.begin(), expect.end())));
  }
  static std::vector<double> uint8_densities(const std::vector<unsigned char>& b,
                                             std::size_t skip) {
    std::vector<double> d;
    for (std::size_t i = skip; i < b.size(); ++i) d.push_back(b[i] / 255.0);
    return d;
  }
};

TEST_F(RealVolumeTest, Tooth) {
  VolumeSource s = src(file("tooth_103x94x161_uint8.raw"));
  s.dims = glm::ivec3(103, 94, 161);
  s.type = "uint8";
  const ivr::Volume v = ivr::load_volume(s);
  check(v, 103, 94, 161, uint8_densities(read_bytes(s.path), 0));
  EXPECT_EQ(v.spacing, glm::dvec3(1.0));
}

TEST_F(RealVolumeTest, HeadsqInt16LittleEndian) {
  VolumeSource s = src(file("headsq_64x64x93_int16le.raw"));
  s.dims = glm::ivec3(64, 64, 93);
  s.type = "int16";
  s.spacing = glm::dvec3(3.2, 3.2, 1.5);
  const auto b = read_bytes(s.path);
  std::vector<double> raw, mapped;
  for (std::size_t i = 0; i + 1 < b.size(); i += 2) {
    raw.push_back(double(std::int16_t(std::uint16_t(b[i] | b[i + 1] << 8))));
    mapped.push_back((raw.back() + 32768) / 65535);
  }
  EXPECT_EQ(*std::max_element(raw.begin(), raw.end()), 3926);  // as the data README states
  EXPECT_EQ(*std::min_element(raw.begin(), raw.end()), 0);
  const ivr::Volume v = ivr::load_volume(s);
  check(v, 64, 64, 93, mapped);
  EXPECT_EQ(v.spacing, glm::dvec3(3.2, 3.2, 1.5));
  s.range = glm::dvec2(0, 3926);
  const ivr::Volume w = ivr::load_volume(s);
  EXPECT_EQ(*std::max_element(w.data.begin(), w.data.end()), 1.0f);
  EXPECT_EQ(*std::min_element(w.data.begin(), w.data.end()), 0.0f);
}

TEST_F(RealVolumeTest, Neghip) {
  VolumeSource s = src(file("neghip_64x64x64_uint8.raw"));
  s.dims = glm::ivec3(64);
  s.type = "uint8";
  const ivr::Volume v = ivr::load_volume(s);
  check(v, 64, 64, 64, uint8_densities(read_bytes(s.path), 0));
  const double zeros = double(std::count(v.data.begin(), v.data.end(), 0.0f)) / v.data.size();
  EXPECT_NEAR(zeros, 0.54, 0.01);  // "54 % zeros" per the data README
}

TEST_F(RealVolumeTest, C60Cvol) {
  const std::string path = file("C60Large_128x128x128_uint8.cvol");
  const ivr::Volume v = ivr::load_volume(src(path));
  check(v, 128, 128, 128, uint8_densities(read_bytes(path), 64));
  EXPECT_EQ(v.spacing, glm::dvec3(1.0 / 128));
}

}  // namespace
