// cli_tune_test.cpp — `ivr tune`: the quick case on the test device writes the JSON record (a
// timed winner among the candidates for every kernel the device launches), --emit-entries prints
// rows in the database's format, bad arguments end in one line and a non-zero status.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

// {"kernel", "vendor", "device", x, y},  // medians …
const std::regex kRow(
    R"re(^\{"([a-z_]+)", "((?:[^"\\]|\\.)*)", "((?:[^"\\]|\\.)*)", (\d+), (\d+)\},  // .*$)re");

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::stringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

class CliTune : public ::testing::Test {
 protected:
  // One quick run of every kernel for the suite (a few seconds on PoCL).
  static void SetUpTestSuite() {
    dir_ = new std::string(temp_dir("cli_tune"));
    run_ = new CliResult(run_cli("tune --quick --json " + *dir_ + "/tune.json"));
  }
  static void TearDownTestSuite() {
    delete run_;
    delete dir_;
  }
  static std::string* dir_;
  static CliResult* run_;
};
std::string* CliTune::dir_ = nullptr;
CliResult* CliTune::run_ = nullptr;

TEST_F(CliTune, QuickRecordsAWinnerAmongTheCandidatesPerKernel) {
  ASSERT_EQ(run_->status, 0) << run_->err;
  EXPECT_TRUE(has(run_->out, device().info().name)) << run_->out;
  const json j = json::parse(file_text(*dir_ + "/tune.json"));
  EXPECT_EQ(j["schema"], "ivr-tune/1");
  EXPECT_EQ(j["device"]["name"], device().info().name);
  EXPECT_EQ(j["device"]["driver"], device().info().driver);
  EXPECT_EQ(j["options"]["volume"], 16);
  EXPECT_EQ(j["options"]["repeats"], 2);
  EXPECT_TRUE(has(j["command"].get<std::string>(), "ivr tune --volume 16 --image 32"));
  std::set<std::string> measured;
  ASSERT_EQ(j["kernels"].size(), tune_kernels().size());
  for (const json& k : j["kernels"]) {
    const std::string name = k["kernel"];
    EXPECT_FALSE(k.contains("failed")) << k.dump();
    if (k.contains("skipped")) {  // the packet kernels on GPUs, the one-ray kernels nowhere
      EXPECT_TRUE(has(k["skipped"].get<std::string>(), "not launched on this device")) << k.dump();
      EXPECT_TRUE(name == "render_packet" || name == "adjoint_packet" ||
                  name == "jacobian_packet" || name == "bricked_packet")
          << name;
      continue;
    }
    measured.insert(name);
    std::set<std::string> timed;
    for (const json& c : k["candidates"]) {
      if (c.contains("skipped")) continue;
      EXPECT_GT(c["median_ms"].get<double>(), 0) << c.dump();
      EXPECT_LE(c["min_ms"].get<double>(), c["median_ms"].get<double>()) << c.dump();
      EXPECT_EQ(c["runs_ms"].size(), 2u) << c.dump();
      timed.insert(c["local"].get<std::string>());
    }
    EXPECT_EQ(timed.count(k["winner"].get<std::string>()), 1u) << k.dump();
    EXPECT_EQ(timed.count(k["fastest"].get<std::string>()), 1u) << k.dump();
    EXPECT_TRUE(timed.count("8x8") && timed.count("16x16")) << k.dump();
    // The driver's choice only where the kernel does not need a group.
    EXPECT_EQ(timed.count("0x0"), k["needs_group"].get<bool>() ? 0u : 1u) << k.dump();
    EXPECT_FALSE(k["check"].get<std::string>().empty());
    EXPECT_TRUE(k["current"].contains("source"));
  }
  for (const char* k : {"render", "adjoint", "jacobian", "project", "backproject", "bricked"})
    EXPECT_EQ(measured.count(k), 1u) << k;
  if (device().info().type == "cpu") {
    EXPECT_EQ(measured.count("render_packet"), 1u);
    EXPECT_EQ(measured.count("adjoint_packet"), 1u);
    EXPECT_EQ(measured.count("jacobian_packet"), 1u);
    EXPECT_EQ(measured.count("bricked_packet"), 1u);
  }
  // The rows in the record are the ones --emit-entries prints: one per measured kernel.
  int rows = 0;
  for (const std::string& line : lines_of(j["entries"].get<std::string>()))
    rows += std::regex_match(line, kRow);
  EXPECT_EQ(rows, int(measured.size())) << j["entries"];
}

TEST_F(CliTune, EmitEntriesPrintsDatabaseRows) {
  const CliResult r =
      run_cli("tune --quick --kernels project,adjoint --statistic min --emit-entries");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 3u) << r.out;
  EXPECT_EQ(lines[0].rfind("// ", 0), 0u) << lines[0];
  EXPECT_TRUE(has(lines[0], device().info().driver)) << lines[0];
  EXPECT_TRUE(has(lines[0], "ivr tune --volume 16")) << lines[0];
  EXPECT_TRUE(has(lines[0], "--statistic min")) << lines[0];
  EXPECT_TRUE(has(lines[0], "minima of 2 runs")) << lines[0];
  std::smatch m;
  ASSERT_TRUE(std::regex_match(lines[1], m, kRow)) << lines[1];
  EXPECT_EQ(m[1], "adjoint");  // the tuner's order, not the argument's
  EXPECT_EQ(m[2], device().info().vendor);
  EXPECT_NE(std::stoi(m[4]), 0);  // the adjoint always has an explicit group
  ASSERT_TRUE(std::regex_match(lines[2], m, kRow)) << lines[2];
  EXPECT_EQ(m[1], "project");
}

TEST_F(CliTune, BadArgumentsEndInOneLine) {
  const std::string json_path = *dir_ + "/bad.json";
  for (const std::string& args : {"--candidates 8x", "--candidates 8x8x", "--candidates=-1x4",
                                  "--candidates 0x4", "--kernels nope", "--volume 2", "--repeats 0",
                                  "--tie 2", "--image x", "--statistic mean", "--bogus"}) {
    const CliResult r = run_cli("tune --quick " + args + " --json " + json_path);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_TRUE(r.out.empty()) << args << ": " << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << args << ": " << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << args << ": " << r.err;
    EXPECT_FALSE(fs::exists(json_path)) << args;
  }
  const CliResult r = run_cli("tune --quick", "IVR_LOCAL_SIZE=8x8");
  EXPECT_NE(r.status, 0);
  EXPECT_TRUE(has(r.err, "IVR_LOCAL_SIZE")) << r.err;
  const CliResult folder = run_cli("tune --quick --json " + *dir_ + "/no/such/folder/t.json");
  EXPECT_NE(folder.status, 0);
  EXPECT_EQ(folder.err.rfind("ivr: error: ", 0), 0u) << folder.err;
}

}  // namespace
}  // namespace ivr::test
