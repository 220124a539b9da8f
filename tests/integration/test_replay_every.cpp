// `rdslam replay --every N` through the real threaded pipeline: the replay processes the
// source's frames 0, N, 2N, ... (dataset indices in --timings), its report counts only those,
// and the report has `init_tracker_ms` {p50, p99, frames} (the frames processed while
// INITIALIZING) and `lost_tracker_ms` (while LOST). Timings are not checked, only that they are
// there.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/run_command.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;
namespace t = testing;
const std::string kBin = RDSLAM_BINARY;

std::vector<long long> timing_indices(const fs::path& csv) {
  std::stringstream in(t::read_text(csv));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "seq,dataset_index,state,arrival_to_tracked_ms,latency_ms,track_ms");
  std::vector<long long> idx;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string seq, index;
    std::getline(ss, seq, ',');
    std::getline(ss, index, ',');
    idx.push_back(std::stoll(index));
  }
  return idx;
}

TEST(ReplayEvery, KeepsEveryNthFrameAndReportsInitTrackerTime) {
  t::ScratchDir dir("replay-every");
  const fs::path report = dir.path() / "r.json", timings = dir.path() / "t.csv";
  const auto r = t::run_command(kBin + " replay 'synth:static_xyz?frames=30' --every 3 --report " +
                                t::shell_quote(report.string()) + " --timings " +
                                t::shell_quote(timings.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::vector<long long> idx = timing_indices(timings);
  ASSERT_EQ(idx.size(), 10u);
  for (size_t k = 0; k < idx.size(); ++k) EXPECT_EQ(idx[k], static_cast<long long>(3 * k));
  const std::string json = t::read_text(report);
  EXPECT_NE(json.find("\"frames\": 10,"), std::string::npos) << json;
  const size_t init = json.find("\"init_tracker_ms\": {");
  ASSERT_NE(init, std::string::npos) << json;
  const std::string block = json.substr(init, json.find('}', init) - init);
  EXPECT_NE(block.find("\"p50\": "), std::string::npos) << block;
  EXPECT_NE(block.find("\"p99\": "), std::string::npos) << block;
  EXPECT_NE(block.find("\"frames\": "), std::string::npos) << block;
  // The first frame only sets the initializer's reference: at least one INITIALIZING frame.
  EXPECT_EQ(block.find("\"p50\": null"), std::string::npos) << block;
  // lost_tracker_ms: present, null percentiles and 0 frames (static_xyz never loses tracking).
  const size_t lost = json.find("\"lost_tracker_ms\": {");
  ASSERT_NE(lost, std::string::npos) << json;
  const std::string lblock = json.substr(lost, json.find('}', lost) - lost);
  EXPECT_NE(lblock.find("\"p50\": null"), std::string::npos) << lblock;
  EXPECT_NE(lblock.find("\"frames\": 0"), std::string::npos) << lblock;
}

TEST(ReplayEvery, RefusesNonPositiveOrFractionalN) {
  for (const char* bad : {"0", "-2", "1.5"}) {
    const auto r = t::run_command(kBin + " replay 'synth:static_xyz?frames=5' --every " + bad);
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.output;
    EXPECT_NE(r.output.find("--every"), std::string::npos) << r.output;
  }
}

}  // namespace
}  // namespace rdslam
