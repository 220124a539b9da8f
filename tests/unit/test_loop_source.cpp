// drivers/loop_source.h: the looped sequence repeats the frames and the ground truth with
// stamps that keep increasing, and refuses what it cannot do at start-up.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "drivers/loop_source.h"
#include "drivers/synth_source.h"

namespace rdslam {
namespace {

std::unique_ptr<FrameSource> tiny(int frames) {
  return open_synth_source("static_xyz", SourceOptions(), frames);
}

TEST(LoopSource, RepeatsFramesAndGroundTruthWithIncreasingStamps) {
  constexpr int kN = 4, kLoops = 3;
  std::unique_ptr<FrameSource> ref = tiny(kN);
  std::vector<cv::Mat> first;
  std::vector<int64_t> stamps;
  Frame f;
  while (ref->read(f, 1000) == SourceStatus::kOk) {
    first.push_back(f.image.clone());
    stamps.push_back(f.stamp_ns);
  }
  ASSERT_EQ(static_cast<int>(first.size()), kN);
  const int64_t period = (stamps.back() - stamps.front()) / (kN - 1);

  std::unique_ptr<FrameSource> loop = make_looped_source(tiny(kN), kLoops, 0.0);
  EXPECT_EQ(loop->info().frame_count, kN * kLoops);
  ASSERT_TRUE(loop->camera().has_value());
  const std::optional<Trajectory> gt = loop->ground_truth();
  ASSERT_TRUE(gt.has_value());
  ASSERT_EQ(static_cast<int>(gt->size()), kN * kLoops);
  int64_t last_stamp = -1;
  for (int i = 0; i < kN * kLoops; ++i) {
    ASSERT_EQ(loop->read(f, 1000), SourceStatus::kOk) << i;
    EXPECT_EQ(cv::norm(f.image, first[i % kN], cv::NORM_INF), 0.0) << "frame " << i;
    const int64_t expect = stamps[i % kN] + (i / kN) * (stamps.back() - stamps.front() + period);
    EXPECT_EQ(f.stamp_ns, expect) << i;
    EXPECT_GT(f.stamp_ns, last_stamp) << i;
    last_stamp = f.stamp_ns;
    // The ground truth of loop k is loop 0's pose at the shifted stamp.
    EXPECT_EQ((*gt)[i].stamp_ns, f.stamp_ns) << i;
    EXPECT_TRUE((*gt)[i].p_world_cam.isApprox((*gt)[i % kN].p_world_cam)) << i;
  }
  EXPECT_EQ(loop->read(f, 1000), SourceStatus::kEndOfStream);
}

TEST(LoopSource, RefusesBadRequestsAtStartUp) {
  EXPECT_THROW(make_looped_source(tiny(3), 0, 0.0), std::runtime_error);
  // 3 BGR 640x480 frames need 2.6 MiB.
  try {
    make_looped_source(tiny(3), 2, 0.0, size_t{1} << 20);
    FAIL() << "a cache above the limit must be refused";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("MiB"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_looped_source(nullptr, 2, 0.0), std::runtime_error);
}

}  // namespace
}  // namespace rdslam
