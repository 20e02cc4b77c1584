// cli_phantom_test.cpp — `ivr phantom`: the .npy (and --nrrd) it writes, read back through the
// project's readers, and its errors: one line, status 1, no file left behind.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "ivr/phantom.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace ivr::test {
namespace {

class CliPhantom : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }

  // Runs `ivr phantom ARGS` expecting failure: returns stderr; the folder must stay empty.
  std::string expect_failure(const std::string& args) {
    const CliResult r = run_cli("phantom " + args);
    EXPECT_EQ(r.status, 1) << args;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    for (const auto& entry : fs::recursive_directory_iterator(dir_))
      if (!entry.is_directory()) ADD_FAILURE() << "left behind: " << entry.path() << " by " << args;
    return r.err;
  }

  std::string dir_;
};

std::string head_of(const std::string& path, std::size_t n) {
  std::ifstream in(path, std::ios::binary);
  std::string s(n, '\0');
  in.read(&s[0], std::streamsize(n));
  s.resize(std::size_t(in.gcount()));
  return s;
}

TEST_F(CliPhantom, WritesFloat32NpyOfShapeNNN) {
  const std::string out = dir_ + "/head.npy";
  const CliResult r = run_cli("phantom shepp-logan --size 16 -o " + out);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_EQ(r.out.find('\n'), r.out.size() - 1) << r.out;  // one line: what was written
  EXPECT_NE(r.out.find("16x16x16"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(out), std::string::npos) << r.out;

  EXPECT_NE(head_of(out, 128).find("'descr': '<f4'"), std::string::npos);  // float32
  const NpyArray a = load_npy(out);
  EXPECT_EQ(a.shape, (std::vector<std::size_t>{16, 16, 16}));
  EXPECT_EQ(fs::file_size(out) - 16 * 16 * 16 * sizeof(float), 128u);  // header + data only
  const Volume v = phantom("shepp-logan", 16);
  ASSERT_EQ(a.data.size(), v.data.size());
  for (std::size_t i = 0; i < v.data.size(); ++i) ASSERT_EQ(float(a.data[i]), v.data[i]) << i;
  EXPECT_FALSE(fs::exists(dir_ + "/head.nrrd"));  // only with --nrrd
}

TEST_F(CliPhantom, SeededEllipsoidsAndNrrd) {
  for (const char* seed : {"3", "4"}) {
    const std::string out = dir_ + "/e" + seed + ".npy";
    const CliResult r = run_cli(std::string("phantom ellipsoids --size 12 --seed ") + seed +
                                " -o " + out + " --nrrd");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find(dir_ + "/e" + seed + ".nrrd"), std::string::npos) << r.out;
  }
  const NpyArray a = load_npy(dir_ + "/e3.npy"), b = load_npy(dir_ + "/e4.npy");
  EXPECT_NE(a.data, b.data);
  const Volume want = phantom("ellipsoids", 12, 3);
  for (std::size_t i = 0; i < want.data.size(); ++i) ASSERT_EQ(float(a.data[i]), want.data[i]);
  // The NRRD holds the same volume, spacing 1, as the project's reader sees it.
  VolumeSource src;
  src.path = dir_ + "/e3.nrrd";
  const Volume n = load_volume(src);
  EXPECT_EQ(n.nx, 12);
  EXPECT_EQ(n.ny, 12);
  EXPECT_EQ(n.nz, 12);
  EXPECT_EQ(n.spacing, glm::dvec3(1.0));
  EXPECT_EQ(n.data, want.data);
  // Nothing but the outputs: no staging file left.
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) files += entry.is_regular_file();
  EXPECT_EQ(files, 4u);
}

TEST_F(CliPhantom, ErrorsWriteNothing) {
  const std::string out = " -o " + dir_ + "/p.npy";
  EXPECT_NE(expect_failure("cube --size 8" + out).find("unknown phantom 'cube' (known: "),
            std::string::npos);
  EXPECT_NE(
      expect_failure("shepp-logan --size 0" + out + " --nrrd").find("size must be in 1..1024"),
      std::string::npos);
  EXPECT_NE(expect_failure("ellipsoids --size 1025" + out).find("got 1025"), std::string::npos);
  EXPECT_NE(expect_failure("shepp-logan --size 8 -o " + dir_ + "/p.raw").find("extension .npy"),
            std::string::npos);
  EXPECT_NE(
      expect_failure("shepp-logan --size 8 -o " + dir_ + "/missing/p.npy").find("does not exist"),
      std::string::npos);
  expect_failure("shepp-logan" + out);                                      // --size is required
  expect_failure("ellipsoids --size 8 --seed 18446744073709551616" + out);  // 2^64
  expect_failure("shepp-logan --size 8 --seed -2" + out);                   // not an unsigned seed
  expect_failure("shepp-logan --size eight" + out);                         // not a number
  // An output path that cannot be written (a folder of that name), with and without --nrrd.
  fs::create_directory(dir_ + "/taken.npy");
  for (const char* extra : {"", " --nrrd"}) {
    const CliResult r = run_cli("phantom shepp-logan --size 8 -o " + dir_ + "/taken.npy" + extra);
    EXPECT_EQ(r.status, 1);
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_TRUE(fs::is_directory(dir_ + "/taken.npy"));
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_EQ(entry.path().filename(), "taken.npy") << "left behind: " << entry.path();
  }
}

}  // namespace
}  // namespace ivr::test
