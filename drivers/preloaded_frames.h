// A recorded source held in memory: read once, then replayed by independent readers.
//
// Users: `rdslam bench pipeline` (the benchmark then times the SLAM stages, not the synthetic
// renderer or the PNG decoder) and tests that run several configurations on the same frames
// (a synthetic scene rendered once instead of once per run). Each frame is a deep copy of the
// source's image (0.9 MB at 640x480 BGR).
//
// A Reader's read() copies the stored image into the caller's frame (a memcpy, as a camera
// driver's DMA copy; no allocation once the caller's frame has the size) and stamps
// Frame::arrival_mono_ns with CLOCK_MONOTONIC at that moment, so capture-to-publish latency
// stays meaningful; stamps, sequence numbers and dataset indices are the recorded ones.
//
// Ownership: PreloadedFrames owns the frames, the camera and the ground truth; a Reader borrows
// them and must not outlive them. Threads: immutable after construction, so readers may run on
// different threads; each Reader is read by one thread (as every FrameSource).
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "core/frame_source.h"

namespace rdslam {

class PreloadedFrames {
 public:
  // Reads `src` to its end. Timeouts and faults are skipped; after 1000 of them the preload
  // stops with what it has (a live source never ends and cannot be preloaded).
  explicit PreloadedFrames(FrameSource& src);

  size_t size() const { return frames_.size(); }
  double megabytes() const { return static_cast<double>(bytes_) / (1024.0 * 1024.0); }

  // A replay of the preloaded frames from the first; info().frame_count is size().
  class Reader : public FrameSource {
   public:
    explicit Reader(const PreloadedFrames& frames) : p_(frames) {}
    SourceStatus read(Frame& out, int timeout_ms) override;
    const SourceInfo& info() const override { return p_.info_; }
    std::optional<CameraModel> camera() const override { return p_.camera_; }
    std::optional<Trajectory> ground_truth() const override { return p_.ground_truth_; }
    SourceCounters counters() const override;

   private:
    const PreloadedFrames& p_;
    size_t next_ = 0;
  };

 private:
  SourceInfo info_;
  std::optional<CameraModel> camera_;
  std::optional<Trajectory> ground_truth_;
  std::vector<Frame> frames_;
  size_t bytes_ = 0;
};

}  // namespace rdslam
