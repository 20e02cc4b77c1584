// cli_reconstruct_test.cpp — `ivr reconstruct`: a density run end to end (every output, the loss
// curve, --json with volume error and held-out PSNR), the TF outputs, Ctrl-C / SIGTERM and
// --resume bit for bit, and one clear error with nothing written for every bad input.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "reconstruct/reconstruct_support.hpp"
#include "reconstruct/svg_check.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

std::set<std::string> listing(const std::string& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// The loss column of PREFIX_loss.csv (checking its header).
std::vector<double> losses(const std::string& csv) {
  std::istringstream in(file_text(csv));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "iteration,level,views,loss,prior,lr,seconds");
  std::vector<double> out;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string cell;
    for (int c = 0; c < 4; ++c) std::getline(row, cell, ',');
    out.push_back(std::stod(cell));
  }
  return out;
}

// The CSV without its last column (seconds differ from run to run).
std::string without_seconds(const std::string& csv) {
  std::istringstream in(file_text(csv));
  std::string out;
  for (std::string line; std::getline(in, line);) out += line.substr(0, line.rfind(',')) + "\n";
  return out;
}

bool is_png(const std::string& path) {
  return file_text(path).rfind("\x89PNG\r\n\x1a\n", 0) == 0;
}

// A 16³ phantom under the emission–absorption TF, 8 views of 32² about z (the training scene),
// 3 views about y (held out); the targets of both rendered by `ivr render`.
class CliReconstruct : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    const Volume truth = phantom("shepp-logan", 16, 1, 2);
    save_npy(dir_ + "/truth.npy", {16, 16, 16}, truth.data.data());
    scene_ = scene_text(orbit(8, "[0, 0, 1]", 0, 32), kPhantomTf);
    write_file(dir_ + "/scene.json", scene_);
    write_file(dir_ + "/held.json", scene_text(orbit(3, "[0, 1, 0]", 10, 32), kPhantomTf));
    for (const char* name : {"scene", "held"}) {
      const CliResult r =
          run_cli("render " + dir_ + "/" + name + ".json -o " + dir_ + "/" + name + "_targets.npy");
      ASSERT_EQ(r.status, 0) << r.err;
    }
  }

  static std::string scene_text(const std::string& cameras, const std::string& tf) {
    return R"({"volume": {"file": "truth.npy"}, "model": "emission_absorption", "tf": )" + tf +
           R"(, "background": [0, 0, 0], "cameras": [)" + cameras +
           R"(], "integrator": {"scheme": "midpoint", "step": 0.5}})";
  }

  std::string base() const {
    return "reconstruct " + dir_ + "/scene.json --targets " + dir_ + "/scene_targets.npy -o " +
           prefix();
  }
  std::string prefix() const { return dir_ + "/out"; }

  // Runs `args` and checks the failure contract (status 1, one "ivr: error:" line on stderr,
  // nothing on stdout, no file added to the folder); returns stderr.
  std::string expect_failure(const std::string& args) {
    const std::set<std::string> before = listing(dir_);
    const CliResult r = run_cli(args);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.out;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    EXPECT_EQ(listing(dir_), before) << "written despite the error: " << args;
    return r.err;
  }

  std::string dir_, scene_;
};

TEST_F(CliReconstruct, DensityWritesEveryOutputAndReportsVolumeErrorAndHeldOutPsnr) {
  const CliResult r = run_cli(base() + " --iterations 40 --init constant:0.5 --truth " + dir_ +
                              "/truth.npy --held-out " + dir_ + "/held.json --held-out-targets " +
                              dir_ + "/held_targets.npy --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["iterations"], 40);
  EXPECT_EQ(j["optimizer"], "adam");
  EXPECT_DOUBLE_EQ(j["lr"].get<double>(), 0.025);  // the automatic lr
  EXPECT_EQ(j["levels"], json::parse("[[4, 4, 4], [8, 8, 8], [16, 16, 16]]"));
  EXPECT_GT(j["iterations_per_second"].get<double>(), 0);
  EXPECT_GT(j["seconds"].get<double>(), 0);
  EXPECT_LT(j["loss_final"].get<double>(), 0.1 * j["loss_first"].get<double>());
  // From a constant 0.5 (relative error ~0.9 against this phantom) to well below.
  EXPECT_LT(j["volume_error"].get<double>(), 0.5);
  EXPECT_GT(j["held_out_psnr"].get<double>(), 20.0);
  EXPECT_FALSE(j.contains("resumed_from"));

  const std::string p = prefix();
  const std::vector<std::string> expected = {
      p + "_density.npy", p + "_density.nrrd", p + "_loss.csv",  p + "_loss.svg",
      p + "_before.png",  p + "_after.png",    p + "_target.png"};
  EXPECT_EQ(j["outputs"].get<std::vector<std::string>>(), expected);
  for (const std::string& o : expected) EXPECT_TRUE(fs::exists(o)) << o;
  for (const char* png : {"_before.png", "_after.png", "_target.png"})
    EXPECT_TRUE(is_png(p + png)) << png;
  EXPECT_TRUE(file_text(p + "_density.nrrd").rfind("NRRD", 0) == 0);
  const NpyArray v = load_npy(p + "_density.npy");
  EXPECT_EQ(v.dtype, "float32");
  EXPECT_EQ(v.shape, (std::vector<std::size_t>{16, 16, 16}));
  EXPECT_FALSE(fs::exists(p + "_checkpoint.json")) << "removed once the run is complete";
  for (const auto& e : fs::directory_iterator(dir_))  // no checkpoint file of any iteration
    EXPECT_EQ(e.path().filename().string().find("_checkpoint"), std::string::npos) << e.path();

  // The loss falls: the last iteration's is far below the first's.
  const std::vector<double> l = losses(p + "_loss.csv");
  ASSERT_EQ(l.size(), 40u);
  EXPECT_DOUBLE_EQ(l.front(), j["loss_first"].get<double>());
  EXPECT_LT(l.back(), 0.1 * l.front());

  // The loss plot: well-formed SVG with both axis titles, decade labels that bracket the CSV's
  // losses within a decade each side, iterations up to the 40th, the three levels and a legend.
  std::vector<XmlElement> svg;
  ASSERT_NO_THROW(svg = parse_xml(file_text(p + "_loss.svg")));
  ASSERT_EQ(svg.front().name, "svg");
  std::map<std::string, std::vector<std::string>> text;
  for (const XmlElement& e : svg)
    if (e.name == "text") text[e.attributes.at("class")].push_back(e.text);
  EXPECT_EQ(text["x-title"], std::vector<std::string>{"iteration"});
  EXPECT_EQ(text["y-title"], std::vector<std::string>{"loss (MSE, log scale)"});
  EXPECT_EQ(text["title"],
            std::vector<std::string>{"ivr reconstruct: density, adam lr 0.025, 40 iterations"});
  EXPECT_EQ(text["level"], (std::vector<std::string>{"4³", "8³", "16³"}));
  EXPECT_EQ(text["legend"], (std::vector<std::string>{"image loss (MSE)", "level change"}));
  std::vector<double> ticks;
  for (const std::string& t : text["y-tick"]) ticks.push_back(tick_value(t));
  ASSERT_GE(ticks.size(), 2u);
  const double lo = *std::min_element(l.begin(), l.end()),
               hi = *std::max_element(l.begin(), l.end());
  EXPECT_LE(*std::min_element(ticks.begin(), ticks.end()), lo);
  EXPECT_GT(*std::min_element(ticks.begin(), ticks.end()), lo / 10);
  EXPECT_GE(*std::max_element(ticks.begin(), ticks.end()), hi);
  EXPECT_LT(*std::max_element(ticks.begin(), ticks.end()), hi * 10);
  ASSERT_FALSE(text["x-tick"].empty());
  EXPECT_EQ(text["x-tick"].front(), "0");
  EXPECT_EQ(text["x-tick"].back(), "40");

  // Not a terminal: a plain progress line every max(1, 40/20) = 2 iterations.
  const std::regex line(
      R"(iteration (\d+)/40 loss \d\.\d{3}e[-+]\d+ prior 0 lr 0\.025 \d+\.\d it/s eta \d+s)");
  std::istringstream err(r.err);
  int lines = 0;
  for (std::string s; std::getline(err, s); ++lines) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(s, m, line)) << s;
    EXPECT_EQ(std::stoi(m[1]), 2 * (lines + 1));
  }
  EXPECT_EQ(lines, 20);

  // The human summary.
  const CliResult h = run_cli(base() + " --iterations 3 --truth " + dir_ + "/truth.npy");
  ASSERT_EQ(h.status, 0) << h.err;
  EXPECT_TRUE(has(h.out, "reconstructed density in 3 iteration(s)")) << h.out;
  EXPECT_TRUE(has(h.out, "volume error")) << h.out;
  EXPECT_TRUE(has(h.out, "-> " + p + "_density.npy")) << h.out;
}

TEST_F(CliReconstruct, TfWritesItsValuesAndJsonThatParsesBack) {
  // Start from a TF 30-40 % off in extinction and colour; the volume is known.
  write_file(dir_ + "/start.json",
             scene_text(orbit(8, "[0, 0, 1]", 0, 32), R"({"type": "piecewise_linear", "points": [
         {"density": 0, "color": [0, 0, 0], "extinction": 0},
         {"density": 1, "color": [0.7, 0.7, 0.7], "extinction": 5},
         {"density": 2, "color": [0.5, 0.5, 0.5], "extinction": 22}]})"));
  const CliResult r =
      run_cli("reconstruct " + dir_ + "/start.json --targets " + dir_ + "/scene_targets.npy -o " +
              prefix() + " --wrt tf --iterations 15 --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["optimizer"], "lbfgs");  // the automatic choice for the TF alone
  EXPECT_LT(j["loss_final"].get<double>(), 0.01 * j["loss_first"].get<double>());
  const std::string p = prefix();
  EXPECT_FALSE(fs::exists(p + "_density.npy"));
  EXPECT_EQ(j["outputs"][0], p + "_tf.npy");
  EXPECT_EQ(j["outputs"][1], p + "_tf.json");

  const NpyArray values = load_npy(p + "_tf.npy");
  EXPECT_EQ(values.dtype, "float32");
  ASSERT_EQ(values.shape, (std::vector<std::size_t>{3, 4}));
  const TransferFunction tf = parse_tf(file_text(p + "_tf.json"), "PREFIX_tf.json");
  ASSERT_EQ(tf.kind, TfKind::piecewise_linear);
  ASSERT_EQ(tf.points.size(), 3u);
  const TransferFunction truth = parse_tf(kPhantomTf);
  for (std::size_t k = 0; k < 3; ++k) {
    const TfPoint& q = tf.points[k];
    const double row[4] = {q.color.x, q.color.y, q.color.z, q.extinction};
    for (int c = 0; c < 4; ++c)
      EXPECT_EQ(float(values.data[k * 4 + std::size_t(c)]), float(row[c])) << k << "," << c;
    EXPECT_EQ(q.density, truth.points[k].density);  // densities are not optimised
  }
  EXPECT_NEAR(tf.points[1].extinction, 8, 0.8);  // from 5
}

// `ivr` stopped by `signal` once its stderr holds `wait_for`; its exit status.
int interrupted(const std::vector<std::string>& args, const std::string& err,
                const std::string& wait_for, int signal) {
  const int status = signalled_cli(args, err, wait_for, signal);
  EXPECT_TRUE(WIFEXITED(status)) << "ended by signal " << WTERMSIG(status);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The checkpoint's iteration, after checking the interruption's report and that no result was
// written yet.
int checkpoint_iteration(const std::string& prefix, const std::string& err) {
  EXPECT_FALSE(fs::exists(prefix + "_density.npy"));
  std::ifstream in(prefix + "_checkpoint.json");
  const json j = json::parse(in);
  const int k = j.at("iteration").get<int>();
  // The arrays of its own iteration, and no other checkpoint's.
  EXPECT_EQ(j["density"]["values"], fs::path(prefix).filename().string() + "_checkpoint_density_" +
                                        std::to_string(k) + ".npy");
  EXPECT_TRUE(fs::exists(fs::path(prefix).parent_path() / j["density"]["values"].get<std::string>()));
  std::size_t arrays = 0;
  for (const auto& e : fs::directory_iterator(fs::path(prefix).parent_path()))
    arrays += e.path().filename().string().rfind(fs::path(prefix).filename().string() +
                                                     "_checkpoint_", 0) == 0 &&
              e.path().extension() == ".npy";
  EXPECT_EQ(arrays, 3u);  // density, first and second moments (Adam)
  EXPECT_TRUE(has(file_text(err), "interrupted after iteration " + std::to_string(k) +
                                      " of 60; continue with --resume\n"))
      << file_text(err);
  return k;
}

// Run A goes straight through 60 iterations; run B is stopped by SIGINT on level 1, resumed,
// stopped by SIGTERM, and resumed to the end crossing into level 2: its densities and losses must
// equal A's bit for bit. PoCL runs its default threads: the reconstruction's density gradient is
// summed in fixed point (AdjointOptions::deterministic), so the order in which rays add to a
// voxel does not change its bits.
TEST_F(CliReconstruct, InterruptedRunResumesBitForBit) {
  const std::string env;
  const std::string options = " --iterations 60 --init constant:0.5 --checkpoint-every 1";
  const CliResult a = run_cli(base() + "A" + options, env);
  ASSERT_EQ(a.status, 0) << a.err;

  const std::string p = prefix() + "B", err = dir_ + "/B.err";
  const std::vector<std::string> args = {"reconstruct",
                                         dir_ + "/scene.json",
                                         "--targets",
                                         dir_ + "/scene_targets.npy",
                                         "-o",
                                         p,
                                         "--iterations",
                                         "60",
                                         "--init",
                                         "constant:0.5",
                                         "--checkpoint-every",
                                         "1"};
  // Levels of 60 iterations: 1-8 (4³), 9-25 (8³), 26-60 (16³); progress every 3 iterations.
  ASSERT_EQ(interrupted(args, err, "iteration 9/60", SIGINT), 130);
  const int first = checkpoint_iteration(p, err);
  EXPECT_GE(first, 9);
  EXPECT_LT(first, 60);

  std::vector<std::string> resume = args;
  resume.push_back("--resume");
  const std::string next = "iteration " + std::to_string((first / 3 + 1) * 3) + "/60";
  ASSERT_EQ(interrupted(resume, err, next, SIGTERM), 143);
  const int second = checkpoint_iteration(p, err);
  EXPECT_GT(second, first);
  EXPECT_LT(second, 60);

  const CliResult b = run_cli(base() + "B" + options + " --resume --json", env);
  ASSERT_EQ(b.status, 0) << b.err;
  const json j = json::parse(b.out);
  EXPECT_EQ(j["resumed_from"], second);
  EXPECT_EQ(j["iterations"], 60);
  EXPECT_EQ(file_text(prefix() + "A_density.npy"), file_text(p + "_density.npy"))
      << "the resumed run's densities differ from the uninterrupted run's";
  EXPECT_EQ(without_seconds(prefix() + "A_loss.csv"), without_seconds(p + "_loss.csv"));
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().filename().string().find("checkpoint"), std::string::npos) << e.path();
}

// --device A,B and no mpirun (MultiDeviceReconstruction): with --split slabs each device a slab,
// without it each a share of the views; the densities those of one device to rounding,
// "devices": 2 in --json, the devices' checkpoints written on the way and removed at the end.
TEST_F(CliReconstruct, SeveralDevicesTakeSlabsOrViews) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  const std::string d = std::to_string(device().info().index);
  const std::string options = " --iterations 6 --levels 1 --init constant:0.5 --precision f64 "
                              "--checkpoint-every 2 --json --split slabs --device ";
  const CliResult one = run_cli(base() + "One" + options + d);
  ASSERT_EQ(one.status, 0) << one.err;
  const CliResult two = run_cli(base() + "Two" + options + d + "," + d);
  ASSERT_EQ(two.status, 0) << two.err;
  const nlohmann::json j = nlohmann::json::parse(two.out);
  EXPECT_EQ(j["devices"], 2) << two.out;
  EXPECT_EQ(j["iterations"], 6) << two.out;
  // Over views (the default split): each device a share of every batch's views.
  const CliResult views = run_cli(base() + "Views --iterations 6 --levels 1 --init constant:0.5 "
                                  "--precision f64 --json --device " + d + "," + d);
  ASSERT_EQ(views.status, 0) << views.err;
  EXPECT_EQ(nlohmann::json::parse(views.out)["devices"], 2) << views.out;
  const std::vector<double> a = load_npy(prefix() + "One_density.npy").data;
  for (const char* other : {"Two_density.npy", "Views_density.npy"}) {
    const std::vector<double> b = load_npy(prefix() + other).data;
    ASSERT_EQ(a.size(), b.size());
    double worst = 0, scale = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
      worst = std::max(worst, std::abs(a[i] - b[i])), scale = std::max(scale, std::abs(a[i]));
    EXPECT_LE(worst, 1e-6 * scale) << other;  // (float32 files of float64 iterates to 1e-12)
  }
  for (const char* device_file : {"Two_device0_checkpoint.json", "Two_device1_checkpoint.json"})
    EXPECT_FALSE(fs::exists(prefix() + device_file)) << device_file << " left behind";
}

TEST_F(CliReconstruct, EveryBadInputIsOneLineAndWritesNothing) {
  const std::string b = base() + " --iterations 2";
  EXPECT_TRUE(has(expect_failure(b + " --lr -0.5"), "--lr must be > 0, got -0.5"));
  EXPECT_TRUE(has(expect_failure(b + " --lr 0"), "--lr must be > 0"));
  EXPECT_TRUE(has(expect_failure(b + " --optimizer rmsprop"), "unknown optimizer 'rmsprop'"));
  EXPECT_TRUE(has(expect_failure(b + " --init ones"),
                  "--init: unknown start 'ones' (known: "
                  "scene, zeros, constant:X"));
  EXPECT_TRUE(has(expect_failure(b + " --init constant:x"), "--init: bad constant 'x'"));
  EXPECT_TRUE(has(expect_failure(b + " --resume"), "--resume: no checkpoint"));
  EXPECT_TRUE(has(expect_failure(b + " --optimizer lbfgs --wrt density"), "use adam or sgd"));
  EXPECT_TRUE(has(expect_failure(b + " --wrt colour"), "--wrt: unknown group 'colour'"));
  EXPECT_TRUE(has(expect_failure(b + " --wrt tf --tv 0.1"), "--tv"));
  EXPECT_TRUE(has(expect_failure(b + " --mode forward"), "--mode"));
  EXPECT_TRUE(has(expect_failure(b + " --precision f16"), "f16"));
  EXPECT_TRUE(has(expect_failure(b + " --held-out " + dir_ + "/held.json"), "--held-out-targets"));
  EXPECT_TRUE(has(expect_failure("reconstruct " + dir_ + "/scene.json -o " + prefix()),
                  "--targets is required"));
  // The held-out views' images given as the training targets: both shapes named.
  EXPECT_TRUE(has(expect_failure("reconstruct " + dir_ + "/scene.json --targets " + dir_ +
                                 "/held_targets.npy -o " + prefix()),
                  "has shape (3, 32, 32, 4) but the scene renders (8, 32, 32, 4)"));
  EXPECT_TRUE(has(expect_failure(b + " --held-out " + dir_ + "/held.json --held-out-targets " +
                                 dir_ + "/scene_targets.npy"),
                  "has shape (8, 32, 32, 4) but the scene renders (3, 32, 32, 4)"));
  const Volume small = phantom("shepp-logan", 8);
  save_npy(dir_ + "/small.npy", {8, 8, 8}, small.data.data());
  EXPECT_TRUE(has(expect_failure(b + " --truth " + dir_ + "/small.npy"), "8x8x8"));
  EXPECT_TRUE(has(expect_failure(b + " --truth " + dir_ + "/missing.npy"), "missing.npy"));
  EXPECT_TRUE(has(expect_failure(base() + "/nested/out"), "does not exist"));
}

}  // namespace
}  // namespace ivr::test
