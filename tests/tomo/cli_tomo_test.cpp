// cli_tomo_test.cpp — `ivr project`, `ivr backproject` and `ivr tomo`: shapes, a Shepp–Logan
// reconstruction, the JSON and progress reports, Ctrl-C / SIGTERM, and one clear error with
// nothing written for every bad input.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>

#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

// A .npy of any dtype (`descr` as numpy writes it), for inputs save_npy cannot make.
void write_npy(const std::string& path, const std::string& descr,
               const std::vector<std::size_t>& shape, const void* data, std::size_t bytes) {
  std::string dims;
  for (std::size_t d : shape) dims += std::to_string(d) + ", ";
  std::string header =
      "{'descr': '" + descr + "', 'fortran_order': False, 'shape': (" + dims + "), }";
  header.append(63 - (10 + header.size()) % 64, ' ').push_back('\n');
  std::ofstream out(path, std::ios::binary);
  const unsigned char length[2] = {std::uint8_t(header.size() & 0xff),
                                   std::uint8_t(header.size() >> 8)};
  out.write("\x93NUMPY\x01\x00", 8);
  out.write(reinterpret_cast<const char*>(length), 2);
  out << header;
  out.write(static_cast<const char*>(data), std::streamsize(bytes));
}

class CliTomo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    truth_ = phantom("shepp-logan", 16);
    save_npy(dir_ + "/truth.npy", {16, 16, 16}, truth_.data.data());
    // 24 parallel-beam views on a half orbit about z, one detector pixel per voxel.
    json cameras = json::array();
    for (int k = 0; k < 24; ++k) {
      const double a = M_PI * k / 24;
      cameras.push_back({{"eye", {2 * std::cos(a), 2 * std::sin(a), 0}},
                         {"target", {0, 0, 0}},
                         {"up", {0, 0, 1}},
                         {"projection", "orthographic"},
                         {"ortho_height", 1.0},
                         {"width", 16},
                         {"height", 16}});
    }
    scene_ = {{"volume", {{"file", "truth.npy"}}},
              {"model", "absorption"},
              {"tf", {{"type", "identity"}, {"extinction_scale", 1}, {"color_scale", 1}}},
              {"cameras", cameras},
              {"integrator", {{"scheme", "midpoint"}, {"step", 2.0}}}};  // ignored: exact
    scene_path_ = write_file(dir_ + "/scene.json", scene_.dump());
    json zeros = scene_;
    zeros["volume"] = {{"synthetic", "zeros"}, {"dims", {16, 16, 16}}};
    zeros_path_ = write_file(dir_ + "/zeros.json", zeros.dump());
  }

  // Projects the phantom to P.npy and returns the line integrals.
  NpyArray project() {
    const CliResult r = run_cli("project " + scene_path_ + " -o " + dir_ + "/P.npy");
    EXPECT_EQ(r.status, 0) << r.err;
    return load_npy(dir_ + "/P.npy");
  }

  // Runs `args` and checks the failure contract (status 1, one "ivr: error:" line on stderr,
  // nothing on stdout, no output or temporary file); returns stderr.
  std::string expect_failure(const std::string& args) {
    const CliResult r = run_cli(args);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.out;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    EXPECT_FALSE(fs::exists(out())) << "written despite the error: " << args;
    for (const auto& e : fs::directory_iterator(dir_))
      EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
    return r.err;
  }

  double relative_error(const NpyArray& x) const {
    double num = 0, den = 0;
    for (std::size_t i = 0; i < x.data.size(); ++i) {
      num += std::pow(x.data[i] - truth_.data[i], 2);
      den += std::pow(double(truth_.data[i]), 2);
    }
    return std::sqrt(num / den);
  }

  std::string out() const { return dir_ + "/V.npy"; }

  std::string dir_, scene_path_, zeros_path_;
  json scene_;
  Volume truth_;
};

TEST_F(CliTomo, ProjectAndBackprojectWriteTheirShapesAndAreTransposes) {
  const CliResult r = run_cli("project " + scene_path_ + " -o " + dir_ + "/P.npy --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["rays"], 24 * 16 * 16);
  EXPECT_GT(j["kernel_seconds"].get<double>(), 0);
  EXPECT_EQ(j["output"], dir_ + "/P.npy");
  const NpyArray p = load_npy(dir_ + "/P.npy");
  EXPECT_EQ(p.shape, (std::vector<std::size_t>{24, 16, 16, 1}));

  // ⟨N v, N v⟩ = ⟨v, Nᵀ N v⟩ through the files (float32 outputs: a loose bound).
  const CliResult b = run_cli("backproject " + zeros_path_ + " --images " + dir_ + "/P.npy -o " +
                              out() + " --json");
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_EQ(json::parse(b.out)["shape"], json({16, 16, 16}));
  const NpyArray bp = load_npy(out());
  EXPECT_EQ(bp.shape, (std::vector<std::size_t>{16, 16, 16}));
  double pp = 0, vb = 0;
  for (double x : p.data) pp += x * x;
  for (std::size_t i = 0; i < bp.data.size(); ++i) vb += truth_.data[i] * bp.data[i];
  EXPECT_NEAR(vb / pp, 1.0, 1e-5);

  // An anisotropic grid (X, Y, Z) = (16, 12, 8) and (views, H, W) float64 input.
  json scene = scene_;
  scene["volume"] = {{"synthetic", "zeros"}, {"dims", {16, 12, 8}}};
  const std::string path = write_file(dir_ + "/aniso.json", scene.dump());
  write_npy(dir_ + "/P64.npy", "<f8", {24, 16, 16}, p.data.data(), p.data.size() * 8);
  const CliResult a =
      run_cli("backproject " + path + " --images " + dir_ + "/P64.npy -o " + dir_ + "/B.npy");
  ASSERT_EQ(a.status, 0) << a.err;
  EXPECT_TRUE(has(a.out, "back-projected")) << a.out;
  EXPECT_EQ(load_npy(dir_ + "/B.npy").shape, (std::vector<std::size_t>{8, 12, 16}));
}

// With --precision f64 the files hold float64, so ⟨N v, y⟩ = ⟨v, Nᵀ y⟩ holds from them to the
// library's 1e-12 (float32 files: ~1e-8 at best); float32 stays the default.
TEST_F(CliTomo, Float64OutputsKeepTheTransposeIdentityInTheFiles) {
  ASSERT_EQ(run_cli("project " + scene_path_ + " -o " + dir_ + "/P.npy --precision f64").status, 0);
  const NpyArray p = load_npy(dir_ + "/P.npy");
  EXPECT_EQ(p.dtype, "float64");
  std::vector<double> y = uniform(p.data.size(), 19);
  for (double& v : y) v -= 0.5;
  write_npy(dir_ + "/Y.npy", "<f8", {24, 16, 16, 1}, y.data(), y.size() * 8);
  const CliResult b = run_cli("backproject " + zeros_path_ + " --images " + dir_ + "/Y.npy -o " +
                              out() + " --precision f64");
  ASSERT_EQ(b.status, 0) << b.err;
  const NpyArray nty = load_npy(out());
  EXPECT_EQ(nty.dtype, "float64");
  double left = 0, right = 0, pn = 0, yn = 0;
  for (std::size_t i = 0; i < y.size(); ++i) left += p.data[i] * y[i], pn += p.data[i] * p.data[i],
                                             yn += y[i] * y[i];
  for (std::size_t i = 0; i < nty.data.size(); ++i) right += double(truth_.data[i]) * nty.data[i];
  EXPECT_LE(std::abs(left - right) / std::sqrt(pn * yn), 1e-12) << left << " vs " << right;

  const CliResult t = run_cli("tomo " + zeros_path_ + " --projections " + dir_ + "/P.npy -o " +
                              dir_ + "/T.npy --iterations 2 --precision f64");
  ASSERT_EQ(t.status, 0) << t.err;
  EXPECT_EQ(load_npy(dir_ + "/T.npy").dtype, "float64");
  ASSERT_EQ(run_cli("project " + scene_path_ + " -o " + dir_ + "/P32.npy").status, 0);
  EXPECT_EQ(load_npy(dir_ + "/P32.npy").dtype, "float32");
}

TEST_F(CliTomo, CglsReconstructsTheProjectedPhantomAndReportsEveryIteration) {
  project();
  const CliResult r = run_cli("tomo " + zeros_path_ + " --projections " + dir_ +
                              "/P.npy --solver cgls --iterations 20 -o " + out() + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["solver"], "cgls");
  EXPECT_EQ(j["iterations"], 20);
  EXPECT_EQ(j["stop_reason"], "iterations");
  EXPECT_EQ(j["output"], out());
  ASSERT_EQ(j["history"].size(), 20u);
  for (int k = 0; k < 20; ++k) EXPECT_EQ(j["history"][k]["iteration"], k + 1);
  EXPECT_EQ(j["residual"], j["history"][19]["residual"]);
  EXPECT_LT(j["residual"].get<double>(), 0.1 * j["history"][0]["residual"].get<double>());
  for (const char* key : {"seconds", "setup_seconds", "device", "precision", "max_iterations"})
    EXPECT_TRUE(j.contains(key)) << key;

  // One progress line per iteration on stderr.
  const std::regex line(R"(iteration (\d+)/20  residual \d\.\d{3}e[-+]\d+  \d+\.\d\d s)");
  std::istringstream err(r.err);
  int lines = 0;
  for (std::string l; std::getline(err, l); ++lines) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(l, m, line)) << l;
    EXPECT_EQ(std::stoi(m[1]), lines + 1);
  }
  EXPECT_EQ(lines, 20);

  const NpyArray v = load_npy(out());
  ASSERT_EQ(v.shape, (std::vector<std::size_t>{16, 16, 16}));
  EXPECT_LT(relative_error(v), 0.3);
}

TEST_F(CliTomo, IntensitiesGiveTheSameReconstruction) {
  const NpyArray p = project();
  std::vector<float> intensities(p.data.size());
  for (std::size_t i = 0; i < p.data.size(); ++i) intensities[i] = float(std::exp(-p.data[i]));
  save_npy(dir_ + "/I.npy", p.shape, intensities.data());
  const CliResult r = run_cli("tomo " + zeros_path_ + " --intensities " + dir_ +
                              "/I.npy --solver lsqr --nonneg --iterations 10 -o " + out());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(has(r.out, "lsqr: 10 iteration(s)")) << r.out;
  EXPECT_LT(relative_error(load_npy(out())), 0.3);

  intensities[5] = 0;  // view 0, y 0, x 5: an error without a clamp, fine with one
  save_npy(dir_ + "/I.npy", p.shape, intensities.data());
  const std::string base = "tomo " + zeros_path_ + " --intensities " + dir_ + "/I.npy -o " + out();
  fs::remove(out());
  EXPECT_TRUE(has(expect_failure(base), "(view 0, y 0, x 5)"));
  EXPECT_EQ(run_cli(base + " --iterations 2 --clamp-intensity 1e-3").status, 0);
}

TEST_F(CliTomo, EveryBadInputIsOneLineAndWritesNothing) {
  const NpyArray p = project();
  const std::string tomo = "tomo " + zeros_path_ + " -o " + out() + " --projections ";
  const std::string P = dir_ + "/P.npy";
  std::vector<float> f(p.data.begin(), p.data.end());

  save_npy(dir_ + "/views.npy", {12, 16, 16, 1}, f.data());
  EXPECT_TRUE(has(expect_failure(tomo + dir_ + "/views.npy"),
                  "has shape (12, 16, 16, 1) but the scene's 24 camera(s) of 16x16 need "
                  "(24, 16, 16, 1) or (24, 16, 16)"));
  save_npy(dir_ + "/shape.npy", {24, 16, 8, 2}, f.data());
  EXPECT_TRUE(has(expect_failure(tomo + dir_ + "/shape.npy"), "(24, 16, 8, 2)"));
  f[2 * 256 + 3 * 16 + 4] = NAN;
  save_npy(dir_ + "/nan.npy", p.shape, f.data());
  EXPECT_TRUE(has(expect_failure(tomo + dir_ + "/nan.npy"), "(view 2, y 3, x 4)"));
  const std::vector<std::int16_t> ints(p.data.size());
  write_npy(dir_ + "/int.npy", "<i2", p.shape, ints.data(), ints.size() * 2);
  EXPECT_TRUE(has(expect_failure(tomo + dir_ + "/int.npy"), "expected float32 or float64"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --solver art"), "unknown solver 'art'"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --tv -0.5"), "--tv must be >= 0"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --tv 1 --tikhonov 1"), "not both"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --iterations 0"), "--iterations must be >= 1"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --relaxation 2"), "--relaxation"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --precision f16"), "f16"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --clamp-intensity 0.1"), "--intensities only"));
  EXPECT_TRUE(has(expect_failure(tomo + P + " --intensities " + P), "exactly one"));
  EXPECT_TRUE(has(expect_failure(tomo + dir_ + "/missing.npy"), "missing.npy"));
  EXPECT_TRUE(has(expect_failure("tomo " + dir_ + "/nope.json -o " + out() + " --projections " + P),
                  "nope.json"));
  EXPECT_TRUE(
      has(expect_failure("tomo " + zeros_path_ + " -o " + dir_ + "/V.txt --projections " + P),
          "needs the extension .npy"));
  EXPECT_TRUE(has(expect_failure("backproject " + zeros_path_ + " -o " + out() + " --images " +
                                 dir_ + "/views.npy"),
                  "--images"));
  EXPECT_TRUE(has(expect_failure("backproject " + zeros_path_ + " -o " + out() + " --images " +
                                 dir_ + "/nan.npy"),
                  "(view 2, y 3, x 4)"));
  EXPECT_TRUE(has(expect_failure("project " + dir_ + "/nope.json -o " + out()), "nope.json"));
}

// Starts `ivr tomo` for (practically) ever, waits for its first progress line, sends `signal`
// and returns the exit status; the last iterate and the JSON must still come out.
int interrupted_status(const std::string& dir, const std::string& scene, int signal) {
  const std::string err = dir + "/stderr", out = dir + "/stdout", volume = dir + "/V.npy";
  const std::string projections = dir + "/P.npy";
  fs::remove(err);  // a progress line of an earlier run must not count
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    ::dup2(::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644), 1);
    ::dup2(::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644), 2);
    ::execl(IVR_CLI_PATH, "ivr", "tomo", scene.c_str(), "--projections", projections.c_str(),
            "--iterations", "1000000", "-o", volume.c_str(), "--json", nullptr);
    std::_Exit(127);
  }
  const auto start = std::chrono::steady_clock::now();
  while (true) {
    std::ifstream in(err);
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    if (text.find("iteration 1/") != std::string::npos) break;
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(60)) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
      ADD_FAILURE() << "no progress line within 60 s: " << text;
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(pid, signal);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status)) << "ended by signal " << WTERMSIG(status)
                                 << " instead of stopping cleanly";
  std::ifstream in(out);
  const json j = json::parse(in);
  EXPECT_EQ(j["stop_reason"], "interrupted");
  EXPECT_LT(j["iterations"].get<int>(), 1000000);
  EXPECT_EQ(load_npy(volume).shape, (std::vector<std::size_t>{16, 16, 16}));
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST_F(CliTomo, InterruptStopsCleanlyAndWritesTheLastIterate) {
  project();
  EXPECT_EQ(interrupted_status(dir_, zeros_path_, SIGINT), 130);
  fs::remove(out());
  EXPECT_EQ(interrupted_status(dir_, zeros_path_, SIGTERM), 143);
}

}  // namespace
}  // namespace ivr::test
