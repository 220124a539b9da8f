// `rdslam tune` end to end on a tiny search: 3 configurations of docs/tune/example.yaml on the
// first 40 frames of synth:static_xyz, each a real child `rdslam replay`. Checks that
// best.yaml is accepted by `rdslam config`, that results.jsonl holds one line per run and
// that running the same command again resumes (runs nothing, same best), and that the
// consistency objective scores the same runs with its disagreement term. The parameter
// file's errors reach the command line with the key named.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/support/run_command.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;
namespace t = testing;
const std::string kBin = RDSLAM_BINARY;

size_t line_count(const fs::path& p) {
  std::stringstream in(t::read_text(p));
  size_t n = 0;
  for (std::string l; std::getline(in, l);) n += !l.empty();
  return n;
}

std::string best_line(const std::string& output) {
  const size_t at = output.find("\nbest: ");
  return at == std::string::npos ? "" : output.substr(at, output.find('\n', at + 1) - at);
}

TEST(TuneCli, TinySearchWritesAConfigAndResumes) {
  t::ScratchDir dir("tune-cli");
  const fs::path out = dir.path() / "out";
  const std::string cmd =
      kBin + " tune --sequences synth:static_xyz --params " +
      t::shell_quote(std::string(RDSLAM_SOURCE_DIR) + "/docs/tune/example.yaml") +
      " --budget 3 --frames 40 --jobs 2 --seed 3 --out-dir " + t::shell_quote(out.string());
  const auto first = t::run_command(cmd);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("3 replays (0 from results.jsonl)"), std::string::npos)
      << first.output;
  EXPECT_EQ(line_count(out / "results.jsonl"), 3u);
  EXPECT_TRUE(fs::exists(out / "tune.png"));
  const std::string best = t::read_text(out / "best.yaml");
  EXPECT_NE(best.find("parsac:\n  inlier_threshold_px: "), std::string::npos) << best;
  const auto config = t::run_command(kBin + " config --config " +
                                     t::shell_quote((out / "best.yaml").string()) + " --diff");
  ASSERT_EQ(config.exit_code, 0) << config.output;
  EXPECT_NE(config.output.find("tracker.max_keyframe_interval="), std::string::npos)
      << config.output;

  const auto again = t::run_command(cmd);
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("3 replays (3 from results.jsonl)"), std::string::npos)
      << again.output;
  EXPECT_EQ(line_count(out / "results.jsonl"), 3u);
  EXPECT_FALSE(best_line(first.output).empty()) << first.output;
  EXPECT_EQ(best_line(again.output), best_line(first.output));

  // The same runs scored without ground truth: nothing is replayed (the run keys do not depend
  // on the objective); the disagreement term is computed from the runs' online trajectories
  // (runs/KEY/online.tum), so every configuration that tracked shows a value in its column.
  const auto consistency = t::run_command(cmd + " --objective consistency");
  ASSERT_EQ(consistency.exit_code, 0) << consistency.output;
  EXPECT_NE(consistency.output.find("3 replays (3 from results.jsonl)"), std::string::npos)
      << consistency.output;
  const size_t header = consistency.output.find(" disagree% ");
  ASSERT_NE(header, std::string::npos) << consistency.output;
  std::stringstream table(consistency.output.substr(consistency.output.find('\n', header) + 1));
  int rows = 0;
  for (std::string row; std::getline(table, row) && !row.empty() && rows < 3; ++rows) {
    std::stringstream cols(row);
    std::string rank, id, rung, objective, ate, x;
    cols >> rank >> id >> rung >> objective >> ate >> x;
    EXPECT_GT(std::stod(x), 0.0) << row;
  }
  EXPECT_EQ(rows, 3) << consistency.output;
  EXPECT_NE(consistency.output.find("same order (docs/tune.md"), std::string::npos)
      << consistency.output;
}

TEST(TuneCli, ParameterFileErrorsNameTheKey) {
  t::ScratchDir dir("tune-cli-bad");
  const fs::path params = dir.path() / "p.yaml";
  {
    std::ofstream f(params);
    f << "- {name: parsac.no_such_threshold, min: 1, max: 2}\n";
  }
  const auto r = t::run_command(kBin + " tune --sequences synth:static_xyz --params " +
                                t::shell_quote(params.string()) + " --budget 3 --out-dir " +
                                t::shell_quote((dir.path() / "o").string()));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("parsac.no_such_threshold: unknown configuration key"), std::string::npos)
      << r.output;
  const auto frames = t::run_command(kBin + " tune --sequences tum:/nonexistent --params " +
                                     t::shell_quote(params.string()) + " --frames 40");
  EXPECT_EQ(frames.exit_code, 2) << frames.output;
  EXPECT_NE(frames.output.find("--frames: shortens synth: sequences only"), std::string::npos)
      << frames.output;
}

}  // namespace
}  // namespace rdslam
