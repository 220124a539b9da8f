// drivers/fault_injection_source.h (`rdslam replay --inject SPEC`): the grammar (and its
// errors), and what each fault kind does to the frames of a synthetic source: statuses,
// stamps, pixels, and the counters the pipeline copies (skipped, reopens, faults).
#include "drivers/fault_injection_source.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <stdexcept>
#include <vector>

#include "drivers/synth_source.h"

namespace rdslam {
namespace {

constexpr int kFrames = 12;

std::unique_ptr<FrameSource> injected(const std::string& spec) {
  return make_fault_injection_source(open_synth_source("static_xyz", SourceOptions(), kFrames),
                                     parse_fault_spec(spec));
}

struct Read {
  SourceStatus status;
  cv::Mat image;
  int64_t stamp_ns = 0, index = -1;
};

std::vector<Read> read_all(FrameSource& s) {
  std::vector<Read> out;
  Frame f;
  for (;;) {
    const SourceStatus st = s.read(f, 1000);
    if (st == SourceStatus::kEndOfStream) break;
    out.push_back(
        {st, st == SourceStatus::kOk ? f.image.clone() : cv::Mat(), f.stamp_ns, f.dataset_index});
  }
  return out;
}

TEST(FaultInjection, ParsesTheGrammar) {
  const std::vector<FaultSpan> p =
      parse_fault_spec("corrupt@40-45,black@60,exposure@120-160:3.5,unplug@170-200");
  ASSERT_EQ(p.size(), 4u);
  EXPECT_EQ(p[0].kind, FaultKind::kCorrupt);
  EXPECT_EQ(p[0].first, 40);
  EXPECT_EQ(p[0].last, 45);
  EXPECT_EQ(p[1].kind, FaultKind::kBlack);
  EXPECT_EQ(p[1].first, 60);
  EXPECT_EQ(p[1].last, 60);
  EXPECT_EQ(p[2].kind, FaultKind::kExposure);
  EXPECT_DOUBLE_EQ(p[2].value, 3.5);
  EXPECT_EQ(p[3].kind, FaultKind::kUnplug);
  EXPECT_STREQ(to_string(p[3].kind), "unplug");
  for (const char* bad :
       {"", "black", "blue@3", "black@", "black@5-3", "black@-3", "black@3:2", "exposure@3",
        "exposure@3:0", "exposure@3:x", "drop@1,,drop@5", "drop@1-2-3", "drop@99999999999999"}) {
    EXPECT_THROW(parse_fault_spec(bad), std::invalid_argument) << bad;
  }
}

TEST(FaultInjection, PixelFaultsOnlyTouchTheirFrames) {
  std::unique_ptr<FrameSource> clean = open_synth_source("static_xyz", SourceOptions(), kFrames);
  const std::vector<Read> ref = read_all(*clean);
  std::unique_ptr<FrameSource> src = injected("black@2,saturated@3-4,exposure@5:0.5,zero@6");
  const std::vector<Read> got = read_all(*src);
  ASSERT_EQ(got.size(), ref.size());
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].status, SourceStatus::kOk) << i;
    EXPECT_EQ(got[i].stamp_ns, ref[i].stamp_ns) << i;
    if (i == 6) {
      EXPECT_TRUE(got[i].image.empty());
      continue;
    }
    cv::Mat expect = ref[i].image.clone();
    if (i == 2) expect.setTo(cv::Scalar::all(0));
    if (i == 3 || i == 4) expect.setTo(cv::Scalar::all(255));
    if (i == 5) ref[i].image.convertTo(expect, -1, 0.5, 0.0);
    EXPECT_EQ(cv::norm(got[i].image, expect, cv::NORM_INF), 0.0) << i;
  }
}

TEST(FaultInjection, StampFaultsStepBackOrRepeat) {
  std::unique_ptr<FrameSource> clean = open_synth_source("static_xyz", SourceOptions(), kFrames);
  const std::vector<Read> ref = read_all(*clean);
  std::unique_ptr<FrameSource> src = injected("stamp_back@3,dup_stamp@5-6");
  const std::vector<Read> got = read_all(*src);
  ASSERT_EQ(got.size(), ref.size());
  // Frame 3: one interval (the last good one, 1 -> 2) before frame 2.
  EXPECT_EQ(got[3].stamp_ns, ref[2].stamp_ns - (ref[2].stamp_ns - ref[1].stamp_ns));
  EXPECT_LT(got[3].stamp_ns, got[2].stamp_ns);
  // Frames 5, 6: frame 4's stamp again.
  EXPECT_EQ(got[5].stamp_ns, ref[4].stamp_ns);
  EXPECT_EQ(got[6].stamp_ns, ref[4].stamp_ns);
  for (int i : {0, 1, 2, 4, 7, 11}) EXPECT_EQ(got[i].stamp_ns, ref[i].stamp_ns) << i;
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(cv::norm(got[i].image, ref[i].image, cv::NORM_INF), 0.0) << "pixels untouched " << i;
  }
}

TEST(FaultInjection, DropAndUnplugAreCounted) {
  std::unique_ptr<FrameSource> src = injected("drop@2-4,unplug@6-8");
  const std::vector<Read> got = read_all(*src);
  // 12 frames: 0 1 | dropped 2 3 4 | 5 | fault 6, timeout 7 8 | 9 10 11
  std::vector<SourceStatus> want = {
      SourceStatus::kOk,    SourceStatus::kOk,      SourceStatus::kOk,
      SourceStatus::kFault, SourceStatus::kTimeout, SourceStatus::kTimeout,
      SourceStatus::kOk,    SourceStatus::kOk,      SourceStatus::kOk};
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) EXPECT_EQ(got[i].status, want[i]) << i;
  EXPECT_EQ(got[2].index, 5);
  EXPECT_EQ(got[6].index, 9);
  const SourceCounters c = src->counters();
  EXPECT_EQ(c.skipped, 3u);
  EXPECT_EQ(c.reopens, 1u);
  EXPECT_EQ(c.faults, 1u);
  EXPECT_EQ(c.delivered, 6u);
}

TEST(FaultInjection, EncodedFaultsGoThroughTheMjpegDecoder) {
  std::unique_ptr<FrameSource> src = injected("truncate@1-3,corrupt@5-8");
  const std::vector<Read> got = read_all(*src);
  ASSERT_EQ(got.size(), static_cast<size_t>(kFrames));
  for (int i : {1, 2, 3}) EXPECT_EQ(got[i].status, SourceStatus::kFault) << i;  // strict
  int rejected = 0;
  for (int i : {5, 6, 7, 8}) {
    if (got[i].status == SourceStatus::kFault) {
      ++rejected;
    } else {
      EXPECT_EQ(got[i].status, SourceStatus::kOk) << i;
      EXPECT_FALSE(got[i].image.empty()) << i;  // decoded, garbled, but the right size
    }
  }
  EXPECT_EQ(src->counters().faults, 3u + rejected);
  for (int i : {0, 4, 9}) EXPECT_EQ(got[i].status, SourceStatus::kOk) << i;
}

TEST(FaultInjection, EmptyPlanIsTheSourceItself) {
  std::unique_ptr<FrameSource> inner = open_synth_source("static_xyz", SourceOptions(), 2);
  FrameSource* raw = inner.get();
  EXPECT_EQ(make_fault_injection_source(std::move(inner), {}).get(), raw);
  EXPECT_THROW(make_fault_injection_source(nullptr, parse_fault_spec("black@1")),
               std::runtime_error);
}

}  // namespace
}  // namespace rdslam
