// nifti_test.cpp — reading NIfTI-1 (.nii, .nii.gz, .hdr/.img): types, byte order, scaling, errors.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ivr/error.hpp"
#include "ivr/volume_io.hpp"
#include "io/volume_test_support.hpp"

namespace fs = std::filesystem;
using ivr::Status;
using ivr::VolumeSource;
using ivr::test::encode;
using ivr::test::ramp;

namespace {

// The header fields a test sets; the rest of the 348 bytes stay zero.
struct Header {
  int sizeof_hdr = 348;
  std::vector<double> dim = {3, 2, 3, 4};  // dim[0], dim[1], ...
  int datatype = 4;                        // int16
  int bitpix = 16;
  std::vector<double> pixdim = {1, 1, 1, 1};  // pixdim[0..3]
  double vox_offset = 352;
  double slope = 0, inter = 0;
  std::string magic = std::string("n+1\0", 4);
};

std::string header(const Header& h, bool big) {
  std::string b(348, '\0');
  auto put = [&](std::size_t at, const std::string& bytes) { b.replace(at, bytes.size(), bytes); };
  put(0, encode<std::int32_t>({double(h.sizeof_hdr)}, big));
  put(40, encode<std::int16_t>(h.dim, big));
  put(70, encode<std::int16_t>({double(h.datatype), double(h.bitpix)}, big));
  put(76, encode<float>(h.pixdim, big));
  put(108, encode<float>({h.vox_offset, h.slope, h.inter}, big));
  put(254, encode<std::int16_t>({1}, big));  // sform_code: an orientation the reader ignores
  put(280, encode<float>({-2, 0, 0, 90, 0, 2, 0, -126, 0, 0, 2, -72}, big));
  put(344, h.magic);
  return b;
}

// A single-file .nii: header, zero padding (the 4-byte extension flag) up to vox_offset, data.
std::string nii(const Header& h, const std::string& data, bool big = false) {
  std::string b = header(h, big);
  b.resize(std::size_t(h.vox_offset), '\0');
  return b + data;
}

class NiftiTest : public ivr::test::VolumeFileTest {
 protected:
  NiftiTest() : VolumeFileTest("ivr_nifti_") {}
};

TEST_F(NiftiTest, EveryTypeInBothByteOrders) {
  struct Case {
    int code, bits;
    double lo, hi;
    std::string (*encode)(const std::vector<double>&, bool);
  };
  const Case cases[] = {{2, 8, 0, 255, encode<std::uint8_t>},
                        {256, 8, -128, 127, encode<std::int8_t>},
                        {512, 16, 0, 65535, encode<std::uint16_t>},
                        {4, 16, -32768, 32767, encode<std::int16_t>},
                        {768, 32, 0, 4294967295.0, encode<std::uint32_t>},
                        {8, 32, -2147483648.0, 2147483647.0, encode<std::int32_t>},
                        {16, 32, 0, 1, encode<float>},
                        {64, 64, 0, 1, encode<double>}};
  for (const Case& c : cases) {
    for (bool big : {false, true}) {
      SCOPED_TRACE("datatype " + std::to_string(c.code) + (big ? " big" : " little") + " endian");
      Header h;
      h.datatype = c.code;
      h.bitpix = c.bits;
      const std::vector<double> raw = c.hi == 1 ? ramp(0.25) : ramp(3, c.lo == 0 ? 0 : -20);
      const std::string path = write("v.nii", nii(h, c.encode(raw, big), big));
      expect_ramp(load(path), raw, c.lo, c.hi);
    }
  }
}

TEST_F(NiftiTest, XFastestOrderAndSpacing) {
  Header h;
  h.datatype = 16;
  h.bitpix = 32;
  h.pixdim = {-1, -0.5, 2, 0};  // qfac -1; a negative spacing reads as its size, 0 as 1
  std::vector<double> raw(24, 0.0);
  raw[1 + 2 * (2 + 3 * 3)] = 0.75;  // (x, y, z) = (1, 2, 3) in the file
  raw[1] = 0.5;                     // (1, 0, 0)
  raw[2 * 3] = 0.25;                // (0, 0, 1)
  const ivr::Volume v = load(write("order.nii", nii(h, encode<float>(raw))));
  ASSERT_EQ(v.data.size(), 24u);
  auto at = [&](int x, int y, int z) { return v.data[std::size_t(x + v.nx * (y + v.ny * z))]; };
  EXPECT_EQ(at(1, 2, 3), 0.75f);
  EXPECT_EQ(at(1, 0, 0), 0.5f);
  EXPECT_EQ(at(0, 0, 1), 0.25f);
  EXPECT_EQ(std::count(v.data.begin(), v.data.end(), 0.0f), 21);
  EXPECT_EQ(v.spacing, glm::dvec3(0.5, 2, 1));

  VolumeSource s;  // the scene's spacing wins over pixdim
  s.path = write("order2.nii", nii(h, encode<float>(raw)));
  s.spacing = glm::dvec3(3, 2, 1);
  EXPECT_EQ(ivr::load_volume(s).spacing, glm::dvec3(3, 2, 1));
}

TEST_F(NiftiTest, GzipExtensionsAndFourthAxisOfOne) {
  Header h;
  h.datatype = 512;
  h.dim = {4, 2, 3, 4, 1};
  h.vox_offset = 368;  // room for an extension the reader skips
  const std::string file = nii(h, encode<std::uint16_t>(ramp(1000), true) + "trailing", true);
  expect_ramp(load(write_gz("v.nii.gz", file)), ramp(1000), 0, 65535);
  expect_ramp(load(write_gz("V.NII.GZ", file)), ramp(1000), 0, 65535);
  expect_ramp(load(write("plain.nii", file)), ramp(1000), 0, 65535);
  VolumeSource s;  // the format name, for a file whose extension says nothing
  s.path = write_gz("v.bin", file);
  s.format = "nifti";
  expect_ramp(ivr::load_volume(s), ramp(1000), 0, 65535);
}

TEST_F(NiftiTest, HeaderAndImagePair) {
  Header h;
  h.magic = std::string("ni1\0", 4);
  h.vox_offset = 0;
  h.pixdim = {1, 1, 2, 3};
  write("pair.img", encode<std::int16_t>(ramp(-7)));
  const ivr::Volume v = load(write("pair.hdr", header(h, false)));
  expect_ramp(v, ramp(-7), -32768, 32767);
  EXPECT_EQ(v.spacing, glm::dvec3(1, 2, 3));
  write_gz("zipped.img.gz", "xxxx" + encode<std::int16_t>(ramp(5), true));
  h.vox_offset = 4;
  expect_ramp(load(write("zipped.hdr", header(h, true))), ramp(5), -32768, 32767);
  load_error(write("lonely.hdr", header(h, false)), Status::io, {"lonely.img", "no such file"});
}

TEST_F(NiftiTest, SclSlopeMakesFloatData) {
  Header h;  // int16 with a scaling: d = slope * v + inter, used as is (not by the int16 range)
  h.slope = 0.001;
  h.inter = 0.5;
  const std::string data = encode<std::int16_t>(ramp(10, -100));
  const double slope = double(float(0.001)), inter = 0.5;  // as stored in the header
  std::vector<double> want;
  for (double v : ramp(10, -100)) want.push_back(slope * v + inter);
  expect_ramp(load(write("s.nii", nii(h, data))), want);
  VolumeSource s;  // a range maps the scaled values
  s.path = write("s2.nii", nii(h, data));
  s.range = glm::dvec2(0.25, 0.75);
  expect_ramp(ivr::load_volume(s), want, 0.25, 0.75);

  h.slope = 1;  // (1, 0) and slope 0 mean no scaling: the int16 range maps
  h.inter = 0;
  expect_ramp(load(write("one.nii", nii(h, data))), ramp(10, -100), -32768, 32767);
  h.slope = 0;
  h.inter = 5;
  expect_ramp(load(write("zero.nii", nii(h, data))), ramp(10, -100), -32768, 32767);

  h.slope = 2;  // scaled float data; and a scaling that gives negative densities is rejected
  h.inter = 0;
  h.datatype = 16;
  expect_ramp(load(write("f.nii", nii(h, encode<float>(ramp(0.25))))), ramp(0.5));
  h.datatype = 4;
  h.slope = 1;
  h.inter = -1000;
  load_error(write("neg.nii", nii(h, data)), Status::invalid_argument, {"negative density"});
}

TEST_F(NiftiTest, Errors) {
  Header h;
  const std::string data = encode<std::int16_t>(ramp());
  Header bad = h;
  bad.magic = "n+2";
  load_error(write("magic.nii", nii(bad, data)), Status::io, {"magic"});
  load_error(write("notnii.nii", std::string(400, 'x')), Status::io, {"sizeof_hdr"});
  bad = h;
  bad.sizeof_hdr = 540;
  load_error(write("two.nii", nii(bad, data)), Status::io, {"NIfTI-2"});
  load_error(write("cut.nii", nii(h, data).substr(0, 200)), Status::io, {"truncated", "header"});
  load_error(write("short.nii", nii(h, data.substr(0, 40))), Status::io, {"truncated", "48"});
  const std::string gz = write_gz("short.nii.gz", nii(h, data.substr(0, 40)));
  load_error(gz, Status::io, {"truncated gzip data in NIfTI"});
  std::ifstream in(gz, std::ios::binary);
  const std::string zipped((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  load_error(write("cutzip.nii.gz", zipped.substr(0, 30)), Status::io, {"truncated"});
  for (const auto& [code, name] : std::vector<std::pair<int, std::string>>{
           {32, "complex64"}, {128, "rgb24"}, {1024, "int64"}, {1280, "uint64"}, {1, "binary"}}) {
    bad = h;
    bad.datatype = code;
    load_error(write("type.nii", nii(bad, data + data + data + data)), Status::io,
               {"unsupported NIfTI datatype " + std::to_string(code), name});
  }
  bad = h;
  bad.datatype = 3;
  load_error(write("unknown.nii", nii(bad, data)), Status::io, {"unknown NIfTI datatype 3"});
  bad = h;
  bad.dim = {2, 4, 6};
  load_error(write("flat.nii", nii(bad, data)), Status::invalid_argument, {"3-D", "dim[0] = 2"});
  bad.dim = {4, 2, 3, 2, 2};
  load_error(write("time.nii", nii(bad, data)), Status::invalid_argument, {"2x3x2x2"});
  bad.dim = {3, 2, -3, 4};
  load_error(write("negdim.nii", nii(bad, data)), Status::io, {"dim[2] = -3"});
  bad.dim = {9, 2, 3, 4};
  load_error(write("rank.nii", nii(bad, data)), Status::io, {"dim[0] = 9"});
  bad = h;
  bad.vox_offset = 100;
  load_error(write("offset.nii", header(bad, false) + data), Status::io, {"vox_offset 100"});
  bad.vox_offset = 352.5;
  load_error(write("frac2.nii", header(bad, false) + std::string(100, '\0')), Status::io,
             {"vox_offset 352.5"});
}

// The MNI ICBM152 template in ../shared/data: a real gzip-compressed NIfTI-1, uint8.
TEST(NiftiRealData, MniIcbm152) {
  const fs::path path =
      fs::path(IVR_SHARED_DATA_DIR) / "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz";
  if (!fs::exists(path)) GTEST_SKIP() << "no " << path;
  // Inflated here with zlib directly; the voxels are the bytes after vox_offset.
  gzFile f = gzopen(path.c_str(), "rb");
  ASSERT_NE(f, nullptr);
  std::vector<unsigned char> bytes;
  unsigned char buf[1 << 16];
  for (int n; (n = gzread(f, buf, sizeof(buf))) > 0;) bytes.insert(bytes.end(), buf, buf + n);
  gzclose(f);
  ASSERT_GT(bytes.size(), 352u);
  float offset;
  std::memcpy(&offset, &bytes[108], 4);  // little-endian file, little-endian test hosts
  ASSERT_EQ(offset, 352.0f);
  const std::size_t count = std::size_t(197) * 233 * 189;
  ASSERT_EQ(bytes.size(), 352 + count);
  double lo = 255, hi = 0, sum = 0;
  for (std::size_t i = 352; i < bytes.size(); ++i) {
    lo = std::min(lo, double(bytes[i]));
    hi = std::max(hi, double(bytes[i]));
    sum += bytes[i];
  }

  VolumeSource s;
  s.path = path.string();
  const ivr::Volume v = ivr::load_volume(s);
  ASSERT_EQ(v.nx, 197);
  ASSERT_EQ(v.ny, 233);
  ASSERT_EQ(v.nz, 189);
  ASSERT_EQ(v.data.size(), count);
  EXPECT_EQ(v.spacing, glm::dvec3(1.0));
  EXPECT_EQ(*std::min_element(v.data.begin(), v.data.end()), float(lo / 255));
  EXPECT_EQ(*std::max_element(v.data.begin(), v.data.end()), float(hi / 255));
  double got = 0;
  for (float d : v.data) got += d;
  EXPECT_NEAR(got / count, sum / count / 255, 1e-6);
  const double zeros = double(std::count(v.data.begin(), v.data.end(), 0.0f)) / count;
  EXPECT_NEAR(zeros, 0.78, 0.01);  // "78 % zeros" per the data README
  // x fastest: voxel (x, y, z) is byte 352 + x + 197 * (y + 233 * z).
  for (std::size_t i : {std::size_t(0), count / 3 + 17, count / 2 + 101, count - 1})
    EXPECT_EQ(v.data[i], float(bytes[352 + i] / 255.0)) << i;
}

}  // namespace
