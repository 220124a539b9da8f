// Test helper: a recorded source read once into memory and replayed by independent readers.
// Test code only. Ownership: CachedFrames owns the frames; a Reader borrows them and must not
// outlive them. Threads: one reader per thread; the cache is immutable after construction.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "core/frame_source.h"

namespace rdslam::test {

// A recorded source read once into memory (deep copies of every frame), then replayed as
// often as needed by independent readers: runs that compare configurations on the same
// frames render a synthetic scene once instead of once per run (CI time: rendering is about
// a third of an offline run's CPU time). Each frame is an 8-bit image (0.9 MB at 640x480 BGR).
class CachedFrames {
 public:
  explicit CachedFrames(FrameSource& src)
      : info_(src.info()), camera_(src.camera()), ground_truth_(src.ground_truth()) {
    Frame f;
    while (src.read(f, 1000) == SourceStatus::kOk) {
      frames_.push_back(f);
      frames_.back().image = f.image.clone();
    }
  }
  size_t size() const { return frames_.size(); }

  // A reader over the cache, from its first frame; it must not outlive the cache.
  class Reader : public FrameSource {
   public:
    explicit Reader(const CachedFrames& c) : c_(c) {}
    SourceStatus read(Frame& out, int) override {
      if (next_ >= c_.frames_.size()) return SourceStatus::kEndOfStream;
      const Frame& f = c_.frames_[next_++];
      out.format = f.format;
      out.stamp_ns = f.stamp_ns;
      out.arrival_mono_ns = f.arrival_mono_ns;
      out.seq = f.seq;
      out.dataset_index = f.dataset_index;
      f.image.copyTo(out.image);
      return SourceStatus::kOk;
    }
    const SourceInfo& info() const override { return c_.info_; }
    std::optional<CameraModel> camera() const override { return c_.camera_; }
    std::optional<Trajectory> ground_truth() const override { return c_.ground_truth_; }

   private:
    const CachedFrames& c_;
    size_t next_ = 0;
  };

 private:
  SourceInfo info_;
  std::optional<CameraModel> camera_;
  std::optional<Trajectory> ground_truth_;
  std::vector<Frame> frames_;
};

}  // namespace rdslam::test
