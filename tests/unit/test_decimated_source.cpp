// drivers/decimated_source.h (`rdslam replay --every N`): the kept frames are the inner
// source's frames 0, N, 2N, ... with their stamps, dataset indices and images unchanged,
// seq renumbered; ground truth and camera pass through; bad requests fail at start-up.
#include "drivers/decimated_source.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <vector>

#include "drivers/synth_source.h"

namespace rdslam {
namespace {

std::unique_ptr<FrameSource> tiny(int frames) {
  return open_synth_source("static_xyz", SourceOptions(), frames);
}

struct Read {
  std::vector<cv::Mat> images;
  std::vector<int64_t> stamps, indices;
  std::vector<uint64_t> seqs;
};

Read read_all(FrameSource& s) {
  Read r;
  Frame f;
  while (s.read(f, 1000) == SourceStatus::kOk) {
    r.images.push_back(f.image.clone());
    r.stamps.push_back(f.stamp_ns);
    r.indices.push_back(f.dataset_index);
    r.seqs.push_back(f.seq);
  }
  return r;
}

TEST(DecimatedSource, KeepsEveryNthFrameWithItsStamp) {
  constexpr int kN = 10;
  std::unique_ptr<FrameSource> ref_src = tiny(kN);
  const Read all = read_all(*ref_src);
  ASSERT_EQ(static_cast<int>(all.stamps.size()), kN);
  for (int every : {2, 3, 4}) {
    std::unique_ptr<FrameSource> dec = make_decimated_source(tiny(kN), every);
    const int kept = (kN + every - 1) / every;  // frames 0, every, 2 every, ...
    EXPECT_EQ(dec->info().frame_count, kept) << every;
    EXPECT_DOUBLE_EQ(dec->info().nominal_fps, ref_src->info().nominal_fps / every) << every;
    ASSERT_TRUE(dec->camera().has_value());
    const std::optional<Trajectory> gt = dec->ground_truth();
    ASSERT_TRUE(gt.has_value());
    EXPECT_EQ(gt->size(), ref_src->ground_truth()->size()) << "ground truth is not decimated";
    const Read got = read_all(*dec);
    ASSERT_EQ(static_cast<int>(got.stamps.size()), kept) << every;
    for (int k = 0; k < kept; ++k) {
      const int i = k * every;
      EXPECT_EQ(got.stamps[k], all.stamps[i]) << "every " << every << " frame " << k;
      EXPECT_EQ(got.indices[k], all.indices[i]) << "every " << every << " frame " << k;
      EXPECT_EQ(got.seqs[k], static_cast<uint64_t>(k));
      EXPECT_EQ(cv::norm(got.images[k], all.images[i], cv::NORM_INF), 0.0) << every << " " << k;
    }
    Frame f;
    EXPECT_EQ(dec->read(f, 1000), SourceStatus::kEndOfStream);
  }
}

TEST(DecimatedSource, EveryOneIsTheSourceItselfAndBadRequestsThrow) {
  std::unique_ptr<FrameSource> inner = tiny(3);
  FrameSource* raw = inner.get();
  EXPECT_EQ(make_decimated_source(std::move(inner), 1).get(), raw);
  EXPECT_THROW(make_decimated_source(tiny(3), 0), std::runtime_error);
  EXPECT_THROW(make_decimated_source(nullptr, 2), std::runtime_error);
}

}  // namespace
}  // namespace rdslam
