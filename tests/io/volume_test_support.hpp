// volume_test_support.hpp — shared fixture for the volume-reading tests: temp folder, files,
// checks.
#pragma once
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "ivr/error.hpp"
#include "ivr/volume_io.hpp"

namespace ivr::test {

inline VolumeSource src(const std::string& path) {
  VolumeSource s;
  s.path = path;
  return s;
}

// Bytes of `values` as type T, little or big endian (independent of the library's code).
template <class T>
std::string encode(const std::vector<double>& values, bool big = false) {
  std::string out;
  for (double v : values) {
    const T t = static_cast<T>(v);
    char b[sizeof(T)];
    std::memcpy(b, &t, sizeof(T));
    const std::uint16_t one = 1;
    const bool host_big = *reinterpret_cast<const unsigned char*>(&one) == 0;
    if (big != host_big) std::reverse(b, b + sizeof(T));
    out.append(b, sizeof(T));
  }
  return out;
}

// Values 0..23 of a 2x3x4 (X x Y x Z) volume in file order, x fastest.
inline std::vector<double> ramp(double scale = 1, double offset = 0) {
  std::vector<double> v(24);
  for (int i = 0; i < 24; ++i) v[i] = offset + scale * i;
  return v;
}

// A fresh temp folder per test, named `prefix`, the process id and the test's name.
class VolumeFileTest : public ::testing::Test {
 protected:
  explicit VolumeFileTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           (prefix_ + std::to_string(::getpid()) + "_" + info->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::string write(const std::string& name, const std::string& bytes) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }
  // Written through zlib's gzopen/gzwrite.
  std::string write_gz(const std::string& name, const std::string& bytes) {
    const std::string path = (dir_ / name).string();
    gzFile f = gzopen(path.c_str(), "wb");
    EXPECT_NE(f, nullptr);
    EXPECT_EQ(gzwrite(f, bytes.data(), unsigned(bytes.size())), int(bytes.size()));
    gzclose(f);
    return path;
  }
  static Volume load(const std::string& path) { return load_volume(src(path)); }
  // Expects f() to throw ivr::Error with `status`, one line, naming `path` and each of `words`.
  static void expect_error(const std::function<void()>& f, Status status, const std::string& path,
                           const std::vector<std::string>& words = {}) {
    try {
      f();
      ADD_FAILURE() << "no ivr::Error thrown for " << path;
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_STREQ(status_name(e.status()), status_name(status)) << msg;
      EXPECT_NE(msg.find(path), std::string::npos) << "message does not name the file: " << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
      for (const std::string& w : words) EXPECT_NE(msg.find(w), std::string::npos) << msg;
    }
  }
  // Expects loading `path` to throw ivr::Error with `status`, one line, naming `path` and `words`.
  static void load_error(const std::string& path, Status status,
                         const std::vector<std::string>& words) {
    expect_error([&] { load(path); }, status, path, words);
  }
  // Expects the 2x3x4 volume v to hold `raw` mapped by d = (raw - lo) / (hi - lo).
  static void expect_ramp(const Volume& v, const std::vector<double>& raw, double lo = 0,
                          double hi = 1) {
    ASSERT_EQ(v.nx, 2);
    ASSERT_EQ(v.ny, 3);
    ASSERT_EQ(v.nz, 4);
    ASSERT_EQ(v.data.size(), 24u);
    for (int i = 0; i < 24; ++i) EXPECT_FLOAT_EQ(v.data[i], float((raw[i] - lo) / (hi - lo))) << i;
  }

  std::filesystem::path dir_;

 private:
  std::string prefix_;
};

}  // namespace ivr::test
