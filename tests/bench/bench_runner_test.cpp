// bench_runner_test.cpp — ivr-bench as a user runs it: a quick run writes versioned JSON and CSV
// with every result checked and timed, --compare finds the same run equal and a faster baseline
// a regression, and bad options are one line and a non-zero status.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

#ifdef IVR_BENCH_PATH

namespace ivr::test {
namespace {

using nlohmann::json;

CliResult bench(const std::string& args) {
  return run_program(IVR_BENCH_PATH, args);
}

// One small run shared by the tests: render, tomography and the compile suite, no Python.
const std::string& quick_run() {
  static const std::string prefix = [] {
    const std::string p = temp_dir("bench_runner_quick") + "/quick";
    const CliResult r = bench(
        "--quick --suite compile,render,tomo --budget 0.05 --min-runs 2 "
        "--max-runs 3 --baselines '' -o " +
        p);
    EXPECT_EQ(r.status, 0) << r.err;
    return p;
  }();
  return prefix;
}

json read_json(const std::string& path) {
  std::ifstream in(path);
  return json::parse(in);
}

void expect_compare_finds_the_same_run_equal_and_a_slower_one_a_regression();

TEST(BenchRunner, QuickRunWritesCheckedResultsAndCompareFindsRegressions) {
  const json doc = read_json(quick_run() + ".json");
  EXPECT_EQ(doc["schema"], "ivr-bench/1");
  EXPECT_FALSE(doc["ivr_version"].get<std::string>().empty());
  EXPECT_GT(doc["machine"]["logical_cores"].get<int>(), 0);
  ASSERT_FALSE(doc["devices"].empty());
  EXPECT_FALSE(doc["devices"][0]["driver"].get<std::string>().empty());
  EXPECT_TRUE(doc["failures"].empty());
  int timed = 0, native = 0, compiles = 0;
  for (const json& r : doc["results"]) {
    const json& m = r["metrics"];
    if (r["suite"] == "compile") {
      ++compiles;
      EXPECT_GT(m["compile_cold_s"].get<double>(), m["compile_cached_s"].get<double>())
          << r["case"];
      continue;
    }
    ASSERT_TRUE(r.contains("check")) << r["case"];
    EXPECT_TRUE(r["check"]["passed"].get<bool>()) << r["case"] << " " << r["implementation"];
    EXPECT_LE(r["check"]["error"].get<double>(), r["check"]["tolerance"].get<double>());
    ASSERT_TRUE(m.contains("median_s")) << r["case"];
    EXPECT_LE(m["min_s"].get<double>(), m["median_s"].get<double>());
    EXPECT_LE(m["median_s"].get<double>(), m["max_s"].get<double>());
    EXPECT_GE(m["runs"].get<int>(), 2);
    EXPECT_LE(m["runs"].get<int>(), 3);
    EXPECT_GT(m["peak_host_bytes"].get<double>(), 0);
    ++timed;
    native += r["implementation"] == "native";
  }
  EXPECT_EQ(compiles, 3);
  EXPECT_GE(timed, 6);  // render: ivr and native; tomo: 4 operations
  EXPECT_EQ(native, 1);
  // The ratio of the native marcher against ivr on the same case.
  bool ratio = false;
  for (const json& r : doc["ratios"]) ratio |= r["suite"] == "render" && r["baseline"] == "native";
  EXPECT_TRUE(ratio);

  const std::string csv = file_text(quick_run() + ".csv");
  EXPECT_EQ(csv.rfind("device,suite,case,implementation,metric,value\n", 0), 0u);
  EXPECT_TRUE(has(csv, ",render,v64_i128_s0.500,ivr,median_s,"));
  EXPECT_TRUE(has(csv, ",compile,render,ivr,compile_cold_s,"));
  expect_compare_finds_the_same_run_equal_and_a_slower_one_a_regression();
}

// --compare on the quick run (called by the test above: each test is a process of its own, and
// the quick run is the expensive part).
void expect_compare_finds_the_same_run_equal_and_a_slower_one_a_regression() {
  const std::string base = quick_run() + ".json";
  CliResult same = bench("--compare " + base + " --input " + base);
  EXPECT_EQ(same.status, 0) << same.err;
  EXPECT_TRUE(has(same.out, "0 beyond")) << same.out;
  EXPECT_FALSE(has(same.out, "REGRESSION"));

  // A baseline twice as fast for every case: every case regressed.
  json doc = read_json(base);
  for (json& r : doc["results"])
    if (r["metrics"].contains("median_s"))
      r["metrics"]["median_s"] = r["metrics"]["median_s"].get<double>() / 2;
  const std::string faster = temp_dir("bench_runner_compare") + "/faster.json";
  std::ofstream(faster) << doc.dump();
  CliResult slower = bench("--compare " + faster + " --input " + base + " --threshold 0.5");
  EXPECT_EQ(slower.status, 3) << slower.err;
  EXPECT_TRUE(has(slower.out, "REGRESSION")) << slower.out;
  // Within a threshold above 100 %, none.
  EXPECT_EQ(bench("--compare " + faster + " --input " + base + " --threshold 1.5").status, 0);
}

TEST(BenchRunner, BadOptionsAreOneLineAndNonZero) {
  const std::string out = temp_dir("bench_runner_bad") + "/bad";
  struct Bad {
    std::string args, message;
  } cases[] = {
      {"--suite nosuch", "unknown suite 'nosuch'"},
      {"--baselines jax,numba", "unknown baseline 'numba'"},
      {"--device no-such-device-anywhere", "no OpenCL device matches"},
      {"--input x.json", "--input needs --compare"},
      {"--compare " + out + "_missing.json --input " + out + "_missing.json", "cannot read"},
      {"--min-runs 5 --max-runs 2", "--max-runs is below --min-runs"},
  };
  for (const Bad& b : cases) {
    const CliResult r = bench(b.args + " -o " + out);
    EXPECT_NE(r.status, 0) << b.args;
    EXPECT_TRUE(has(r.err, b.message)) << b.args << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << b.args << ": " << r.err;
    EXPECT_FALSE(std::ifstream(out + ".json").good()) << b.args;
  }
  // A file that is not a results document.
  write_file(out + "_other.json", "{\"schema\": \"something-else\"}");
  const CliResult r = bench("--compare " + out + "_other.json --input " + out + "_other.json");
  EXPECT_EQ(r.status, 1);
  EXPECT_TRUE(has(r.err, "not an ivr-bench results file")) << r.err;
}

TEST(BenchRunner, MissingBaselineEnvironmentIsSkippedWithANote) {
  const std::string p = temp_dir("bench_runner_nopython") + "/nopython";
  const CliResult r = bench(
      "--quick --suite render --budget 0.02 --min-runs 1 --max-runs 1 "
      "--baselines jax --python /nonexistent/python -o " +
      p);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(has(r.err, "Python baselines skipped")) << r.err;
  bool noted = false;
  const json doc = read_json(p + ".json");
  for (const json& rec : doc["results"])
    if (rec["implementation"] == "jax") {
      noted = true;
      EXPECT_TRUE(has(rec["note"].get<std::string>(), "no baseline environment")) << rec["note"];
      EXPECT_TRUE(rec["metrics"].empty());
    }
  EXPECT_TRUE(noted) << file_text(p + ".json");
}

}  // namespace
}  // namespace ivr::test

#endif  // IVR_BENCH_PATH
