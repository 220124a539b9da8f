// Fault tolerance (issue 25): `rdslam replay synth:static_xyz --inject SPEC` through the whole
// threaded pipeline with the real SLAM stages, one replay per fault kind
// (drivers/fault_injection_source.h). Each replay must exit normally, count the fault where
// the pipeline can tell (the report's `source_faults` block, the same counters as
// rdslam.status_t), and be TRACKING again within 30 frames after the fault ends. The fault
// starts after the map exists (the replay is tracking on the frame before it), and the scene
// is the static office: tracking is expected to recover everywhere.
#include <gtest/gtest.h>

#include <filesystem>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/run_command.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;
namespace t = testing;
const std::string kBin = RDSLAM_BINARY;

constexpr int kFirst = 30;   // first damaged frame (static_xyz initializes at frame 13)
constexpr int kFrames = 75;  // replayed frames: the fault (10 frames) and 35 after it

struct Row {
  long long index = -1;
  std::string state;
};

std::vector<Row> read_timings(const fs::path& csv) {
  std::stringstream in(t::read_text(csv));
  std::string line;
  std::getline(in, line);  // header
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string seq, index, state;
    std::getline(ss, seq, ',');
    std::getline(ss, index, ',');
    std::getline(ss, state, ',');
    rows.push_back({std::stoll(index), state});
  }
  return rows;
}

// The integer value of "key": N inside the report's `block` object ("" = the first "key").
long long counter(const std::string& json, const std::string& block, const std::string& key) {
  size_t b = 0, end = json.size();
  if (!block.empty()) {
    b = json.find("\"" + block + "\": {");
    if (b == std::string::npos) return -1;
    end = json.find('}', b);
  }
  const size_t k = json.find("\"" + key + "\": ", b);
  if (k == std::string::npos || k > end) return -1;
  return std::stoll(json.substr(k + key.size() + 4));
}

struct Count {
  const char* block;
  const char* key;
  long long min, max;  // inclusive
};

struct Case {
  const char* name;
  const char* spec;  // KIND@FIRST[-LAST]
  int last;          // last damaged frame
  std::vector<Count> counts;
};

void PrintTo(const Case& c, std::ostream* os) {
  *os << c.spec;
}

class FaultInjection : public ::testing::TestWithParam<Case> {};

TEST_P(FaultInjection, SurvivesCountsAndTracksAgainWithin30Frames) {
  const Case& c = GetParam();
  t::ScratchDir dir(std::string("fault-") + c.name);
  const fs::path report = dir.path() / "r.json", timings = dir.path() / "t.csv";
  const auto r =
      t::run_command(kBin + " replay 'synth:static_xyz?frames=" + std::to_string(kFrames) +
                     "' --inject " + c.spec + " --report " + t::shell_quote(report.string()) +
                     " --timings " + t::shell_quote(timings.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string json = t::read_text(report);
  for (const Count& n : c.counts) {
    const long long v = counter(json, n.block, n.key);
    EXPECT_GE(v, n.min) << n.block << "." << n.key << "\n" << json;
    EXPECT_LE(v, n.max) << n.block << "." << n.key << "\n" << json;
  }
  // The books: every frame of the source was processed, or rejected, or counted missing.
  const long long processed = counter(json, "", "frames");
  long long missing = 0;
  for (const char* key : {"faults", "timeouts", "frames_invalid", "stamps_rejected"}) {
    missing += counter(json, "source_faults", key);
  }
  missing += counter(json, "dropped", "source_skipped");
  EXPECT_EQ(processed + missing, kFrames) << json;
  const std::vector<Row> rows = read_timings(timings);
  bool tracking_before = false;
  long long recovered = -1;
  for (const Row& row : rows) {
    if (row.index == kFirst - 1) tracking_before = row.state == "TRACKING";
    if (row.index > c.last && recovered < 0 && row.state == "TRACKING") recovered = row.index;
  }
  EXPECT_TRUE(tracking_before) << "not tracking on frame " << kFirst - 1 << ": nothing to test";
  ASSERT_GE(recovered, 0) << "never TRACKING after the fault\n" << r.output;
  EXPECT_LE(recovered - c.last, 30) << "TRACKING again only at frame " << recovered;
}

// Frames 30..39 (one frame for stamp_back) in every case. The replay is lossless and
// deterministic, so the counts are exact, except for corrupt: libjpeg notices some damaged
// frames (a source fault) and decodes the others into garbled images (tracked).
INSTANTIATE_TEST_SUITE_P(
    Kinds, FaultInjection,
    ::testing::Values(
        Case{"corrupt", "corrupt@30-39", 39, {{"source_faults", "faults", 1, 10}}},
        Case{"truncate", "truncate@30-39", 39, {{"source_faults", "faults", 10, 10}}},
        Case{"zero", "zero@30-39", 39, {{"source_faults", "frames_invalid", 10, 10}}},
        Case{
            "black",
            "black@30-39",
            39,
            {{"source_faults", "frames_blank", 10, 10}, {"source_faults", "exposure_jumps", 0, 0}}},
        Case{"saturated", "saturated@30-39", 39, {{"source_faults", "frames_blank", 10, 10}}},
        Case{"exposure_down",
             "exposure@30-39:0.3",
             39,
             {{"source_faults", "exposure_jumps", 2, 2}, {"source_faults", "frames_blank", 0, 0}}},
        Case{"exposure_up", "exposure@30-39:3", 39, {{"source_faults", "exposure_jumps", 2, 2}}},
        Case{"stamp_back", "stamp_back@30", 30, {{"source_faults", "stamps_rejected", 1, 1}}},
        Case{"dup_stamp", "dup_stamp@30-39", 39, {{"source_faults", "stamps_rejected", 10, 10}}},
        Case{"drop", "drop@30-39", 39, {{"dropped", "source_skipped", 10, 10}}},
        Case{"unplug",
             "unplug@30-39",
             39,
             {{"source_faults", "faults", 1, 1},
              {"source_faults", "timeouts", 9, 9},
              {"source_faults", "reopens", 1, 1}}}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

}  // namespace
}  // namespace rdslam
