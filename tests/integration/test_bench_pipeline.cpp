// `rdslam bench pipeline` (issue 10) on a short synthetic source: the JSON report has the
// keys the issue names, with values that are consistent with each other. No timing bars
// (timings belong in docs/benchmarks.md, not in pass/fail tests).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <string>

namespace {

struct BenchRun {
  int rc = -1;
  std::string out;
};

BenchRun run_bench(const std::string& args) {
  // stderr (log lines) is discarded: stdout must be the JSON document alone.
  const std::string cmd = std::string(RDSLAM_BINARY) + " bench pipeline " + args + " 2>/dev/null";
  BenchRun r;
  FILE* f = popen(cmd.c_str(), "r");
  if (!f) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), f)) > 0) r.out.append(buf, n);
  r.rc = pclose(f);
  return r;
}

// JSON is a subset of YAML 1.2's flow syntax: yaml-cpp parses the report.
void check_stage(const YAML::Node& stages, const char* name) {
  ASSERT_TRUE(stages[name].IsMap()) << name;
  const double p50 = stages[name]["p50"].as<double>();
  const double p99 = stages[name]["p99"].as<double>();
  EXPECT_GE(p50, 0.0) << name;
  EXPECT_GE(p99, p50) << name;
}

TEST(BenchPipeline, ThreadedJsonHasIssueKeys) {
  const BenchRun r = run_bench("'synth:static_xyz?frames=12' --json");
  ASSERT_EQ(r.rc, 0) << r.out;
  const YAML::Node j = YAML::Load(r.out);
  ASSERT_TRUE(j.IsMap()) << r.out;
  EXPECT_EQ(j["frames"].as<int>(), 12);
  EXPECT_EQ(j["mode"].as<std::string>(), "pipeline");
  EXPECT_EQ(j["width"].as<int>(), 640);
  EXPECT_EQ(j["height"].as<int>(), 480);
  EXPECT_GT(j["fps"].as<double>(), 0.0);
  EXPECT_GT(j["total_s"].as<double>(), 0.0);
  // fps is frames over the wall time of the run.
  EXPECT_NEAR(j["fps"].as<double>() * j["total_s"].as<double>(), 12.0, 0.01);
  const YAML::Node stages = j["stages"];
  check_stage(stages, "tracker");
  check_stage(stages, "mapper");
  check_stage(stages, "capture");
  EXPECT_GT(stages["tracker"]["p50"].as<double>(), 0.0);
  ASSERT_TRUE(j["latency_ms"].IsMap());
  const double lat50 = j["latency_ms"]["p50"].as<double>();
  EXPECT_GT(lat50, 0.0);
  EXPECT_GE(j["latency_ms"]["p99"].as<double>(), lat50);
  const double rss = j["peak_rss_mb"].as<double>();
  EXPECT_GT(rss, 1.0);
  EXPECT_LT(rss, 4096.0);
  // Lossless: nothing may be dropped.
  EXPECT_EQ(j["dropped"].as<int>(), 0);
  EXPECT_EQ(j["publish_overflows"].as<int>(), 0);
  // Common report keys (firmware_app/report.h).
  for (const char* k : {"tracked_frames", "tracked_ratio", "initialized_frame",
                        "tracked_ratio_after_init", "ate_rmse_m", "ate_rmse_pct_path"}) {
    EXPECT_TRUE(j[k].IsDefined()) << k;
  }
}

TEST(BenchPipeline, SingleThreadIsDeterministic) {
  const BenchRun a = run_bench("'synth:static_xyz?frames=10' --json --single-thread");
  const BenchRun b = run_bench("'synth:static_xyz?frames=10' --json --single-thread");
  ASSERT_EQ(a.rc, 0) << a.out;
  ASSERT_EQ(b.rc, 0) << b.out;
  const YAML::Node ja = YAML::Load(a.out), jb = YAML::Load(b.out);
  EXPECT_EQ(ja["mode"].as<std::string>(), "single-thread");
  EXPECT_EQ(ja["frames"].as<int>(), 10);
  check_stage(ja["stages"], "tracker");
  check_stage(ja["stages"], "mapper");
  // Same tracking outcome on every run (the point of the callgrind mode).
  EXPECT_EQ(ja["tracked_frames"].as<int>(), jb["tracked_frames"].as<int>());
  EXPECT_EQ(ja["initialized_frame"].as<int>(), jb["initialized_frame"].as<int>());
}

TEST(BenchPipeline, FramesLimitAndBadArguments) {
  const BenchRun r = run_bench("'synth:static_xyz?frames=20' --json --single-thread --frames 5");
  ASSERT_EQ(r.rc, 0) << r.out;
  const YAML::Node j = YAML::Load(r.out);
  EXPECT_EQ(j["frames"].as<int>(), 5);
  EXPECT_NE(run_bench("'synth:static_xyz?frames=5' --frames -3").rc, 0);
  EXPECT_NE(run_bench("no-such-scheme:xyz --json").rc, 0);
}

}  // namespace
