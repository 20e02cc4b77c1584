// cli_faults_test.cpp — the CLI killed for real (SIGKILL) in the middle of an output write and of
// a checkpoint write (paused there by $IVR_TEST_PAUSE_BEFORE_RENAME, lib/io/files.cpp), and writing
// to a full file system (RLIMIT_FSIZE): the previous file stays whole, the run resumes, and a
// failed write is one clear error with no partial file.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "ivr/phantom.hpp"
#include "ivr/volume_io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

class CliFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    const Volume truth = phantom("shepp-logan", 16);
    save_npy(dir_ + "/truth.npy", {16, 16, 16}, truth.data.data());
    const json orbit = {{"orbit", {{"views", 4}, {"radius", 2}, {"width", 16}, {"height", 16}}}};
    scene_ = dir_ + "/scene.json";
    write_file(scene_, json{{"volume", {{"file", "truth.npy"}}},
                            {"model", "emission_absorption"},
                            {"tf", {{"type", "identity"}, {"extinction_scale", 4}}},
                            {"cameras", json::array({orbit})},
                            {"integrator", {{"scheme", "midpoint"}, {"step", 0.5}}}}
                           .dump());
  }
  std::string dir_, scene_;
};

TEST_F(CliFaults, KilledDuringAnOutputWriteLeavesThePreviousFile) {
  const std::string out = dir_ + "/P.npy";
  ASSERT_EQ(run_cli("project " + scene_ + " -o " + out).status, 0);
  const std::string before = file_text(out);
  const int status =
      signalled_cli({"project", scene_, "-o", out, "--precision", "f64"}, dir_ + "/err",
                    "paused before renaming", SIGKILL, "IVR_TEST_PAUSE_BEFORE_RENAME=P.npy");
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << file_text(dir_ + "/err");
  EXPECT_EQ(file_text(out), before) << "the previous output was changed";
  EXPECT_EQ(load_npy(out).dtype, "float32");  // still the old one
}

// Killed while writing its third checkpoint: the second stays whole and consistent, and a resumed
// run ends with the uninterrupted run's densities, bit for bit.
TEST_F(CliFaults, KilledDuringACheckpointWriteResumes) {
  ASSERT_EQ(run_cli("render " + scene_ + " -o " + dir_ + "/targets.npy").status, 0);
  const std::string common = scene_ + " --targets " + dir_ +
                             "/targets.npy --iterations 6 --init constant:0.5 --checkpoint-every 1";
  ASSERT_EQ(run_cli("reconstruct " + common + " -o " + dir_ + "/A").status, 0);
  const std::vector<std::string> args = {"reconstruct", scene_, "--targets",
                                         dir_ + "/targets.npy", "--iterations", "6",
                                         "--init", "constant:0.5", "--checkpoint-every", "1",
                                         "-o", dir_ + "/B"};
  // The third checkpoint's JSON, then its arrays (the second of them), each paused and killed.
  for (const char* part : {"B_checkpoint.json:3", "B_checkpoint_first:3"}) {
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.path().filename().string().rfind("B_", 0) == 0) fs::remove(e.path());
    const int status = signalled_cli(args, dir_ + "/err", "paused before renaming", SIGKILL,
                                     std::string("IVR_TEST_PAUSE_BEFORE_RENAME=") + part);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << file_text(dir_ + "/err");
    std::ifstream in(dir_ + "/B_checkpoint.json");
    const json j = json::parse(in);  // whole: it parses
    EXPECT_EQ(j["iteration"], 2) << part;
    EXPECT_TRUE(fs::exists(dir_ + "/" + j["density"]["values"].get<std::string>()));
    const CliResult r = run_cli("reconstruct " + common + " -o " + dir_ + "/B --resume --json");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(json::parse(r.out)["resumed_from"], 2);
    EXPECT_EQ(file_text(dir_ + "/A_density.npy"), file_text(dir_ + "/B_density.npy")) << part;
    for (const auto& e : fs::directory_iterator(dir_))  // the run's end removed every piece
      EXPECT_EQ(e.path().filename().string().find("_checkpoint"), std::string::npos) << e.path();
  }
}

// A file-size limit below the output's size (as a full disk): writes fail with EFBIG (SIGXFSZ
// ignored, as it is by processes that handle write errors); the CLI reports one line and leaves
// neither the output nor a temporary file. The limit, 4 MiB, leaves room for what PoCL writes
// while it builds a program its cache already holds (the source and its preprocessed text, up to
// ~2 MiB: ivr keeps no binaries of its own on PoCL, lib/runtime/program_cache.cpp); the output,
// 1024² rays in float64, is 8 MiB.
TEST_F(CliFaults, FullFileSystemIsOneErrorAndNoPartialFile) {
  const std::string out = dir_ + "/P.npy", scene = dir_ + "/large.json";
  write_file(scene, json{{"volume", {{"file", "truth.npy"}}},
                         {"model", "absorption"},
                         {"cameras", json::array({{{"eye", {0.3, -2, 0.4}},
                                                   {"width", 1024},
                                                   {"height", 1024}}})}}
                        .dump());
  // A first run warms the kernel caches, so that the limited run writes nothing but its output
  // and PoCL's temporary files.
  ASSERT_EQ(run_cli("project " + scene + " -o " + dir_ + "/warm.npy --precision f64").status, 0);
  const CliResult r = run_program(
      "bash", "-c 'ulimit -f 4096; trap \"\" XFSZ; exec \"$0\" \"$@\"' " +
                  std::string(IVR_CLI_PATH) + " project " + scene + " -o " + out +
                  " --precision f64");
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
  EXPECT_FALSE(fs::exists(out));
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

}  // namespace
}  // namespace ivr::test
