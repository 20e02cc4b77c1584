// volume_io_test.cpp — reading .npy, NRRD, raw and .cvol: round trips, mapping and errors.
#include "ivr/volume_io.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "ivr/error.hpp"
#include "io/volume_test_support.hpp"

namespace fs = std::filesystem;
using ivr::Status;
using ivr::VolumeSource;
using ivr::test::encode;
using ivr::test::ramp;
using ivr::test::src;

namespace {

// A hand-written .npy: the dict header padded to 64 bytes, then `payload`.
std::string npy(const std::string& descr, const std::vector<std::size_t>& shape,
                const std::string& payload, bool fortran = false, int version = 1) {
  std::string dict = "{'descr': '" + descr + "', 'fortran_order': " + (fortran ? "True" : "False") +
                     ", 'shape': (";
  for (std::size_t n : shape) dict += std::to_string(n) + ", ";
  dict += "), }";
  const std::size_t pre = version == 1 ? 10 : 12;
  while ((pre + dict.size() + 1) % 64 != 0) dict += ' ';
  dict += '\n';
  std::string out = "\x93NUMPY";
  out += char(version);
  out += char(0);
  out += encode<std::uint32_t>({double(dict.size())}).substr(0, pre - 8);
  return out + dict + payload;
}

// A zero 2x3x4 volume with `value` at (x=1, y=2, z=3) only.
std::vector<double> one_hot(double value) {
  std::vector<double> v(24, 0.0);
  v[(3 * 3 + 2) * 2 + 1] = value;
  return v;
}

std::string gzip(const std::string& bytes) {
  const fs::path tmp = fs::temp_directory_path() / ("ivr_gz_" + std::to_string(::getpid()));
  gzFile f = gzopen(tmp.c_str(), "wb");
  gzwrite(f, bytes.data(), unsigned(bytes.size()));
  gzclose(f);
  std::ifstream in(tmp, std::ios::binary);
  std::string out((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  fs::remove(tmp);
  return out;
}

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<unsigned char>((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
}

// A NRRD of a 2x3x4 volume: header with `fields` (each ending in a newline), blank line, data.
std::string nrrd(const std::string& fields, const std::string& data) {
  return "NRRD0004\ndimension: 3\nsizes: 2 3 4\n" + fields + "\n" + data;
}

// A .cvol: 64-byte header (magic, 3 x u64 dims, 3 x f64 voxel size, i32 type, u8 flag, padding).
std::string cvol(int x, int y, int z, double sx, double sy, double sz, int type,
                 const std::string& payload, int compressed = 0) {
  std::string h = "cvol" + encode<std::uint64_t>({double(x), double(y), double(z)}) +
                  encode<double>({sx, sy, sz}) + encode<std::int32_t>({double(type)});
  h += char(compressed);
  h.append(7, '\0');
  return h + payload;
}

class VolumeIoTest : public ivr::test::VolumeFileTest {
 protected:
  VolumeIoTest() : VolumeFileTest("ivr_volume_io_") {}
  ivr::Volume load_raw(const std::string& path, const std::string& type, bool big = false) {
    VolumeSource s = src(path);
    s.dims = glm::ivec3(2, 3, 4);
    s.type = type;
    s.endian = big ? "big" : "little";
    return ivr::load_volume(s);
  }
};

TEST_F(VolumeIoTest, SaveNpyRoundTripsFloat32) {
  std::vector<float> data(24);
  for (int i = 0; i < 24; ++i) data[i] = 0.25f * i;
  const std::string path = (dir_ / "v.npy").string();
  ivr::save_npy(path, {4, 3, 2}, data.data());
  const auto bytes = read_bytes(path);
  ASSERT_EQ((bytes.size() - 24 * 4) % 64, 0u);  // data 64-byte aligned like numpy
  EXPECT_NE(std::string(bytes.begin(), bytes.end()).find("'descr': '<f4'"), std::string::npos);
  expect_ramp(load(path), ramp(0.25));
  EXPECT_EQ(load(path).spacing, glm::dvec3(1.0));
  const ivr::NpyArray a = ivr::load_npy(path);
  EXPECT_EQ(a.shape, (std::vector<std::size_t>{4, 3, 2}));
  for (int i = 0; i < 24; ++i) EXPECT_EQ(a.data[i], 0.25 * i);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1)
      << "temporary file left behind";
}

TEST_F(VolumeIoTest, SaveNpyOneAndZeroDimensions) {
  const float five[5] = {1, 2, 3, 4, 5};
  ivr::save_npy((dir_ / "a.npy").string(), {5}, five);
  const auto bytes = read_bytes((dir_ / "a.npy").string());
  EXPECT_NE(std::string(bytes.begin(), bytes.end()).find("(5,)"), std::string::npos);
  ivr::NpyArray a = ivr::load_npy((dir_ / "a.npy").string());
  EXPECT_EQ(a.shape, std::vector<std::size_t>{5});
  EXPECT_EQ(a.data, (std::vector<double>{1, 2, 3, 4, 5}));
  ivr::save_npy((dir_ / "s.npy").string(), {}, five);
  a = ivr::load_npy((dir_ / "s.npy").string());
  EXPECT_TRUE(a.shape.empty());
  EXPECT_EQ(a.data, std::vector<double>{1});
}

TEST_F(VolumeIoTest, NpyEveryDtypeMapsByItsRange) {
  struct Case {
    std::string descr, payload;
    std::vector<double> raw;
    double lo, hi;
  };
  const std::vector<Case> cases = {
      {"<f4", encode<float>(ramp(0.5)), ramp(0.5), 0, 1},
      {"<f8", encode<double>(ramp(0.5)), ramp(0.5), 0, 1},
      {"|u1", encode<std::uint8_t>(ramp(9)), ramp(9), 0, 255},
      {"|i1", encode<std::int8_t>(ramp(5, -60)), ramp(5, -60), -128, 127},
      {"<u2", encode<std::uint16_t>(ramp(1000)), ramp(1000), 0, 65535},
      {"<i2", encode<std::int16_t>(ramp(-1000)), ramp(-1000), -32768, 32767},
      {"<u4", encode<std::uint32_t>(ramp(1e8)), ramp(1e8), 0, 4294967295.0},
      {"<i4", encode<std::int32_t>(ramp(-5e7)), ramp(-5e7), -2147483648.0, 2147483647},
      {">f4", encode<float>(ramp(0.5), true), ramp(0.5), 0, 1},
      {">u2", encode<std::uint16_t>(ramp(1000), true), ramp(1000), 0, 65535},
      {">i4", encode<std::int32_t>(ramp(-5e7), true), ramp(-5e7), -2147483648.0, 2147483647},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.descr);
    expect_ramp(load(write("v.npy", npy(c.descr, {4, 3, 2}, c.payload))), c.raw, c.lo, c.hi);
  }
}

TEST_F(VolumeIoTest, NpyFortranOrderIsTransposed) {
  std::vector<double> f(24);  // (Z=4, Y=3, X=2) stored z fastest
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 2; ++x) f[z + 4 * (y + 3 * x)] = 100 * z + 10 * y + x;
  const ivr::Volume v = load(write("f.npy", npy("<f4", {4, 3, 2}, encode<float>(f), true)));
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 2; ++x) EXPECT_EQ(v.at(x, y, z), 100 * z + 10 * y + x);
}

TEST_F(VolumeIoTest, NpyVersion2HeaderAndGenericLoad) {
  expect_ramp(load(write("v2.npy", npy("<f4", {4, 3, 2}, encode<float>(ramp()), false, 2))),
              ramp());
  const ivr::NpyArray a = ivr::load_npy(
      write("m.npy", npy("<i2", {2, 3}, encode<std::int16_t>({-3, -2, -1, 0, 1, 2}))));
  EXPECT_EQ(a.shape, (std::vector<std::size_t>{2, 3}));
  EXPECT_EQ(a.data, (std::vector<double>{-3, -2, -1, 0, 1, 2}));  // raw values, no mapping
}

TEST_F(VolumeIoTest, XIsFastestInEveryFormat) {
  const std::vector<double> hot = one_hot(200);
  std::vector<ivr::Volume> vols;
  vols.push_back(load(write("h.npy", npy("|u1", {4, 3, 2}, encode<std::uint8_t>(hot)))));
  vols.push_back(load_raw(write("h.raw", encode<std::uint8_t>(hot)), "uint8"));
  vols.push_back(
      load(write("h.nrrd", nrrd("type: uint8\nencoding: raw\n", encode<std::uint8_t>(hot)))));
  vols.push_back(load(write("h.cvol", cvol(2, 3, 4, 1, 1, 1, 0, encode<std::uint8_t>(hot)))));
  for (const ivr::Volume& v : vols) {
    ASSERT_EQ(v.nx * 100 + v.ny * 10 + v.nz, 234);
    EXPECT_FLOAT_EQ(v.at(1, 2, 3), 200.0f / 255);
    EXPECT_EQ(std::count(v.data.begin(), v.data.end(), 0.0f), 23);
  }
}

TEST_F(VolumeIoTest, NrrdRawWithCommentsKeyValuesBigEndianAndSpacings) {
  const std::string header =
      "NRRD0005\n# a comment\ntype: unsigned short\ndimension: 3\nspace: left-posterior-superior\n"
      "sizes: 2 3 4\nendian: big\nencoding: raw\nspacings: 0.5 2 -3\nsome key:=some: value\n"
      "kinds: domain domain domain\n\n";
  const ivr::Volume v = load(write("v.nrrd", header + encode<std::uint16_t>(ramp(1000), true)));
  expect_ramp(v, ramp(1000), 0, 65535);
  EXPECT_EQ(v.spacing, glm::dvec3(0.5, 2, 3));
}

TEST_F(VolumeIoTest, NrrdGzipAttachedWithSpaceDirections) {
  std::string header =
      "NRRD0004\r\ntype: int16\r\ndimension: 3\r\nsizes: 2 3 4\r\nendian: little\r\n"
      "encoding: gzip\r\nspace directions: (0.5,0,0) (0, 0, 2) (0,3,4)\r\n\r\n";
  const ivr::Volume v = load(write("v.nrrd", header + gzip(encode<std::int16_t>(ramp(-1000)))));
  expect_ramp(v, ramp(-1000), -32768, 32767);
  EXPECT_EQ(v.spacing, glm::dvec3(0.5, 2, 5));
}

TEST_F(VolumeIoTest, NhdrDetachedDataRelativeToTheHeader) {
  fs::create_directories(dir_ / "sub");
  write("sub/data.raw.gz", gzip(encode<float>(ramp(0.5))));
  const std::string gz = write("sub/a.nhdr",
                               "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 3 4\n"
                               "encoding: gz\nendian: little\ndata file: data.raw.gz\n");
  expect_ramp(load(gz), ramp(0.5));
  // Raw with line skip and byte skip; and byte skip -1 (data at the end of the file).
  write("sub/skip.raw", "two\nlines\nXYZ" + encode<std::uint8_t>(ramp(10)));
  expect_ramp(load(write("sub/b.nhdr",
                         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nencoding: raw\n"
                         "datafile: ./skip.raw\nline skip: 2\nbyte skip: 3\n")),
              ramp(10), 0, 255);
  expect_ramp(load(write("sub/c.nhdr",
                         "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 3 4\nencoding: raw\n"
                         "data file: skip.raw\nbyte skip: -1\n")),
              ramp(10), 0, 255);
}

TEST_F(VolumeIoTest, NrrdAsciiTypeAliasesAndLeadingUnitAxis) {
  std::string text;
  for (int i = 0; i < 24; ++i) text += std::to_string(i) + (i % 5 == 4 ? "\n" : " ");
  const std::vector<std::pair<std::string, double>> aliases = {
      {"uchar", 255},         {"unsigned char", 255},
      {"uint8_t", 255},       {"ushort", 65535},
      {"uint16", 65535},      {"unsigned short int", 65535},
      {"uint", 4294967295.0}, {"unsigned int", 4294967295.0},
      {"float", 1},           {"double", 1}};
  for (const auto& [type, scale] : aliases) {
    SCOPED_TRACE(type);
    expect_ramp(load(write("a.nrrd", nrrd("type: " + type + "\nencoding: ascii\n", text))), ramp(),
                0, scale);
  }
  const std::vector<std::pair<std::string, double>> signed_aliases = {
      {"signed char", 128},        {"int8", 128},      {"short", 32768},
      {"short int", 32768},        {"int16_t", 32768}, {"int", 2147483648.0},
      {"signed int", 2147483648.0}};
  for (const auto& [type, off] : signed_aliases) {
    SCOPED_TRACE(type);
    expect_ramp(load(write("s.nrrd", nrrd("type: " + type + "\nencoding: txt\n", text))), ramp(),
                -off, off - 1);
  }
  const ivr::Volume v = load(write("4d.nrrd",
                                   "NRRD0004\ntype: uint8\ndimension: 4\nsizes: 1 2 3 4\n"
                                   "spacings: nan 1 2 3\nencoding: raw\n\n" +
                                       encode<std::uint8_t>(ramp())));
  expect_ramp(v, ramp(), 0, 255);
  EXPECT_EQ(v.spacing, glm::dvec3(1, 2, 3));
}

TEST_F(VolumeIoTest, RawEndiannessAndTypes) {
  expect_ramp(load_raw(write("a.raw", encode<std::uint16_t>(ramp(1000))), "uint16"), ramp(1000), 0,
              65535);
  expect_ramp(load_raw(write("b.raw", encode<std::uint16_t>(ramp(1000), true)), "uint16", true),
              ramp(1000), 0, 65535);
  expect_ramp(load_raw(write("c.raw", encode<float>(ramp(0.5), true)), "float32", true), ramp(0.5));
  expect_ramp(load_raw(write("d.raw", encode<double>(ramp(0.5))), "float64"), ramp(0.5));
  expect_ramp(load_raw(write("e.raw", encode<std::int8_t>(ramp(-5))), "int8"), ramp(-5), -128, 127);
  expect_ramp(load_raw(write("f.raw", encode<std::uint32_t>(ramp(7), true)), "uint32", true),
              ramp(7), 0, 4294967295.0);
}

TEST_F(VolumeIoTest, IntegerTypesMapTheirFullRangeToZeroOne) {
  auto ends = [&](const std::string& type, const std::string& bytes) {
    VolumeSource s = src(write("e.raw", bytes));
    s.dims = glm::ivec3(2, 1, 1);
    s.type = type;
    const ivr::Volume v = ivr::load_volume(s);
    EXPECT_EQ(v.data[0], 0.0f) << type;
    EXPECT_EQ(v.data[1], 1.0f) << type;
  };
  ends("uint8", encode<std::uint8_t>({0, 255}));
  ends("int8", encode<std::int8_t>({-128, 127}));
  ends("uint16", encode<std::uint16_t>({0, 65535}));
  ends("int16", encode<std::int16_t>({-32768, 32767}));
  ends("uint32", encode<std::uint32_t>({0, 4294967295.0}));
  ends("int32", encode<std::int32_t>({-2147483648.0, 2147483647}));
}

TEST_F(VolumeIoTest, RangeAndSpacingOverrides) {
  VolumeSource s = src(write("v.nrrd", nrrd("type: int16\nencoding: raw\nspacings: 3.2 3.2 1.5\n",
                                            encode<std::int16_t>(ramp(100)))));
  s.range = glm::dvec2(0, 4600);
  s.spacing = glm::dvec3(1, 2, 3);
  const ivr::Volume v = ivr::load_volume(s);
  expect_ramp(v, ramp(100), 0, 4600);
  EXPECT_EQ(v.spacing, glm::dvec3(1, 2, 3));
  EXPECT_EQ(load(s.path).spacing, glm::dvec3(3.2, 3.2, 1.5));
  VolumeSource f = src(write("f.npy", npy("<f4", {4, 3, 2}, encode<float>(ramp(1, -10)))));
  f.range = glm::dvec2(-10, 14);  // floats follow the range too
  expect_ramp(ivr::load_volume(f), ramp(1, -10), -10, 14);
  f.range = glm::dvec2(0, 14);  // maps -10 to a negative density
  expect_error([&] { ivr::load_volume(f); }, Status::invalid_argument, f.path,
               {"negative density", "(0, 0, 0)", "range [0, 14]"});
  f.range = glm::dvec2(3, 3);
  expect_error([&] { ivr::load_volume(f); }, Status::invalid_argument, f.path, {"lo < hi"});
  f.range.reset();
  f.spacing = glm::dvec3(1, 0, 1);
  expect_error([&] { ivr::load_volume(f); }, Status::invalid_argument, f.path, {"spacing"});
}

TEST_F(VolumeIoTest, CvolOfEachTypeWithSpacing) {
  const ivr::Volume a =
      load(write("a.cvol", cvol(2, 3, 4, 0.1, 0.2, 0.3, 0, encode<std::uint8_t>(ramp(10)))));
  expect_ramp(a, ramp(10), 0, 255);
  EXPECT_EQ(a.spacing, glm::dvec3(0.1, 0.2, 0.3));
  expect_ramp(load(write("b.cvol", cvol(2, 3, 4, 1, 1, 1, 1, encode<std::uint16_t>(ramp(1000))))),
              ramp(1000), 0, 65535);
  expect_ramp(load(write("c.cvol", cvol(2, 3, 4, 1, 1, 1, 2, encode<float>(ramp(0.5))))),
              ramp(0.5));
}

TEST_F(VolumeIoTest, FormatFieldOverridesTheExtension) {
  VolumeSource s = src(write("v.bin", npy("<f4", {4, 3, 2}, encode<float>(ramp()))));
  s.format = "npy";
  expect_ramp(ivr::load_volume(s), ramp());
  s.format = ".NPY";
  expect_ramp(ivr::load_volume(s), ramp());
  s.format = "vtk";
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, s.path, {"vtk"});
}

// --- errors -------------------------------------------------------------------------------------

TEST_F(VolumeIoTest, MissingFileAndDirectoryAreIoErrors) {
  const std::string missing = (dir_ / "missing.npy").string();
  load_error(missing, Status::io, {"no such file"});
  expect_error([&] { ivr::load_npy(missing); }, Status::io, missing);
  fs::create_directories(dir_ / "d.nrrd");
  expect_error([&] { load((dir_ / "d.nrrd").string()); }, Status::io, (dir_ / "d.nrrd").string(),
               {"directory"});
}

TEST_F(VolumeIoTest, MalformedNpyIsAnIoError) {
  const std::string full = npy("<f4", {4, 3, 2}, encode<float>(ramp()));
  const std::string cut = write("cut.npy", full.substr(0, full.size() - 5));
  load_error(cut, Status::io, {"truncated", "91", "96"});
  const std::string head = write("head.npy", full.substr(0, 40));
  load_error(head, Status::io, {"truncated"});
  const std::string magic = write("magic.npy", "\x93NUMPX" + full.substr(6));
  load_error(magic, Status::io, {"magic"});
  const std::string dtype = write("c8.npy", npy("<c8", {4, 3, 2}, std::string(192, '\0')));
  load_error(dtype, Status::io, {"dtype", "<c8"});
  const std::string obj = write("obj.npy", npy("|O", {1}, std::string(8, '\0')));
  expect_error([&] { ivr::load_npy(obj); }, Status::io, obj, {"dtype"});
  std::string garbled = full;
  garbled.replace(garbled.find("'shape'"), 7, "'shap\"'");
  const std::string bad = write("bad.npy", garbled);
  load_error(bad, Status::io, {"header"});
}

TEST_F(VolumeIoTest, WrongShapesAreInvalidArguments) {
  const std::string two = write("two.npy", npy("<f4", {4, 6}, encode<float>(ramp())));
  load_error(two, Status::invalid_argument, {"3-D", "(4, 6)"});
  const std::string empty = write("empty.npy", npy("<f4", {0, 3, 2}, ""));
  load_error(empty, Status::invalid_argument, {">= 1", "2x3x0"});
  const std::string raw = write("x.raw", std::string(1000, '\0'));
  VolumeSource s = src(raw);
  s.dims = glm::ivec3(10, 10, 11);
  s.type = "uint8";
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, raw,
               {"1000 bytes", "10x10x11", "uint8", "1100"});
  s.type = "uint12";
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, raw, {"uint12"});
  s.type = "";
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, raw, {"type"});
  s.type = "uint8";
  s.endian = "middle";
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, raw, {"middle"});
  s.endian = "little";
  s.dims = glm::ivec3(1 << 16, 1 << 16, 2);
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, raw, {"2147483648"});
  s.dims.reset();
  expect_error([&] { ivr::load_volume(s); }, Status::invalid_argument, raw, {"dims"});
  const std::string flat = write("flat.nrrd",
                                 "NRRD0004\ntype: float\ndimension: 2\n"
                                 "sizes: 4 6\nencoding: raw\n\n" +
                                     encode<float>(ramp()));
  load_error(flat, Status::invalid_argument, {"3-D"});
}

TEST_F(VolumeIoTest, MalformedNrrdIsAnIoError) {
  const std::string body = "type: uint8\ndimension: 3\nsizes: 2 3 4\n";
  const std::string data = encode<std::uint8_t>(ramp());
  const std::string magic = write("m.nrrd", "NRRD9\n" + body + "encoding: raw\n\n" + data);
  load_error(magic, Status::io, {"magic"});
  const std::string bz = write("bz.nrrd", "NRRD0004\n" + body + "encoding: bzip2\n\n" + data);
  load_error(bz, Status::io, {"bzip2", "not supported"});
  const std::string unk = write("unk.nrrd", "NRRD0004\n" + body + "encoding: zstd\n\n" + data);
  load_error(unk, Status::io, {"unknown NRRD encoding 'zstd'"});
  const std::string type =
      write("t.nrrd", nrrd("type: int64\nencoding: raw\n", std::string(192, '\0')));
  load_error(type, Status::io, {"int64"});
  const std::string cut = write("cut.nrrd", "NRRD0004\n" + body + "encoding: raw\n\n" + "abc");
  load_error(cut, Status::io, {"truncated", "24"});
  const std::string nodata = write("no.nhdr", "NRRD0004\n" + body + "encoding: raw\n");
  load_error(nodata, Status::io, {"data file"});
  const std::string lost =
      write("lost.nhdr", "NRRD0004\n" + body + "encoding: raw\ndata file: lost.raw\n");
  expect_error([&] { load(lost); }, Status::io, (dir_ / "lost.raw").string(), {"no such file"});
  const std::string noenc = write("noenc.nrrd", "NRRD0004\n" + body + "\n" + data);
  load_error(noenc, Status::io, {"encoding"});
}

TEST_F(VolumeIoTest, CorruptedGzipIsAnIoError) {
  const std::string header = nrrd("type: float\nendian: little\nencoding: gzip\n", "");
  std::string gz = gzip(encode<float>(ramp(0.5)));
  gz[gz.size() - 6] ^= 0x5a;  // break the CRC32 in the gzip trailer
  const std::string crc = write("crc.nrrd", header + gz);
  load_error(crc, Status::io, {"corrupted gzip"});
  const std::string junk = write("junk.nrrd", header + "this is not gzip data at all");
  load_error(junk, Status::io, {"corrupted gzip"});
  const std::string full = gzip(encode<float>(ramp(0.5)));
  const std::string cut = write("cut.nrrd", header + full.substr(0, full.size() / 2));
  load_error(cut, Status::io, {"truncated gzip"});
}

TEST_F(VolumeIoTest, NonFiniteAndNegativeDensitiesNameTheVoxel) {
  const std::string nan =
      write("nan.npy", npy("<f4", {4, 3, 2}, encode<float>(one_hot(std::nan("")))));
  load_error(nan, Status::invalid_argument, {"NaN", "(1, 2, 3)"});
  const std::string inf =
      write("inf.npy", npy("<f8", {4, 3, 2}, encode<double>(one_hot(-INFINITY))));
  load_error(inf, Status::invalid_argument, {"infinite", "(1, 2, 3)"});
  const std::string neg = write("neg.raw", encode<float>(one_hot(-0.5)));
  expect_error([&] { load_raw(neg, "float32"); }, Status::invalid_argument, neg,
               {"negative density -0.5", "(1, 2, 3)"});
  const std::string big = write("big.npy", npy("<f8", {4, 3, 2}, encode<double>(one_hot(1e300))));
  load_error(big, Status::invalid_argument, {"float32", "(1, 2, 3)"});
}

TEST_F(VolumeIoTest, BadCvolAndUnknownExtension) {
  const std::string lz4 = write("z.cvol", cvol(2, 3, 4, 1, 1, 1, 0, std::string(24, '\0'), 1));
  load_error(lz4, Status::io, {"compressed .cvol (LZ4) is not supported"});
  const std::string type = write("t.cvol", cvol(2, 3, 4, 1, 1, 1, 7, std::string(24, '\0')));
  load_error(type, Status::io, {"data type 7"});
  const std::string cut = write("c.cvol", cvol(2, 3, 4, 1, 1, 1, 1, std::string(24, '\0')));
  load_error(cut, Status::io, {"truncated", "48"});
  const std::string magic = write("m.cvol", "CVOL" + std::string(84, '\0'));
  load_error(magic, Status::io, {"magic"});
  const std::string zero = write("0.cvol", cvol(2, 0, 4, 1, 1, 1, 0, ""));
  load_error(zero, Status::invalid_argument, {"2x0x4"});
  const std::string vti = write("brain.vti.gz", "not read");
  load_error(vti, Status::invalid_argument, {"'.gz'", "extension"});
}

// VolumeSource::planes (a domain worker's slab): the volume keeps its dims and holds only the
// planes chosen from its nz — .npy (C order) and raw read just those bytes, the other formats
// (and Fortran-order .npy) are read whole and cut; every format gives the whole read's values.
TEST_F(VolumeIoTest, PlanesKeepOnlyTheSlabInEveryFormat) {
  const std::vector<double> values = ramp(10);
  const std::string bytes = encode<std::uint8_t>(values);
  std::vector<std::string> paths = {
      write("p.npy", npy("|u1", {4, 3, 2}, bytes)), write("p.raw", bytes),
      write("p.nrrd", nrrd("type: uint8\nencoding: raw\n", bytes)),
      write("p.cvol", cvol(2, 3, 4, 1, 1, 1, 0, bytes))};
  // Fortran order: the same volume stored z fastest.
  std::vector<double> fortran(24);
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 2; ++x) fortran[(x * 3 + y) * 4 + z] = values[(z * 3 + y) * 2 + x];
  paths.push_back(write("f.npy", npy("|u1", {4, 3, 2}, encode<std::uint8_t>(fortran), true)));
  for (const std::string& path : paths) {
    VolumeSource s = src(path);
    if (path.size() > 4 && path.substr(path.size() - 4) == ".raw") s.dims = glm::ivec3(2, 3, 4), s.type = "uint8";
    const ivr::Volume whole = load_volume(s);
    int asked = -1;
    s.planes = [&](int nz) {
      asked = nz;
      return std::pair<int, int>{1, 2};
    };
    const ivr::Volume slab = load_volume(s);
    EXPECT_EQ(asked, 4) << path;
    EXPECT_EQ(slab.nx * 100 + slab.ny * 10 + slab.nz, 234) << path;
    ASSERT_EQ(slab.data.size(), 12u) << path;
    for (std::size_t i = 0; i < 12; ++i) EXPECT_EQ(slab.data[i], whole.data[6 + i]) << path << " " << i;
    s.planes = [](int nz) { return std::pair<int, int>{nz - 1, nz + 1}; };
    expect_error([&] { load_volume(s); }, Status::invalid_argument, path, {"planes 3..5"});
  }
}

}  // namespace
