// Sanity checks on frames as they enter the pipeline (issue 25, fault tolerance): what a
// cheap camera or a broken recording can hand over that the tracker must not see, and what
// it may see but should be counted.
//
// FrameCheck::check() classifies one frame the source delivered as kOk:
//  - kInvalid: an empty (zero-size) image, a pixel type that is not the frame's format
//    (CV_8UC1 for kGray8, CV_8UC3 for kBgr8), or a size other than that of the first
//    accepted frame (a camera does not change its size mid-stream). Rejected: not tracked.
//  - kStampNotIncreasing: stamp_ns <= the last accepted frame's (a clock that stepped
//    back, a duplicated delivery). Rejected: the trajectory and the pose messages stay in
//    time order and the motion model never sees a zero or negative interval.
// Accepted frames are also measured on a sparse grid of at most 32 x 24 pixels (green
// channel of BGR): `blank` when max - min <= kBlankRange grey levels (a black, saturated
// or covered frame: nothing to track), `exposure_jump` when the grid mean differs from the
// last non-blank accepted frame's by more than a factor kExposureJumpRatio (a sudden gain
// or exposure change). Those two only count: the tracker still gets the frame.
//
// Ownership: plain value, no heap. Threads: one thread (the pipeline's capture thread).
#pragma once

#include <cstdint>

#include "core/frame_source.h"

namespace rdslam {

enum class FrameVerdict : uint8_t { kOk = 0, kInvalid = 1, kStampNotIncreasing = 2 };

struct FrameCheckResult {
  FrameVerdict verdict = FrameVerdict::kOk;
  bool blank = false;          // kOk only: no contrast on the sample grid
  bool exposure_jump = false;  // kOk only: grid mean jumped against the last non-blank frame
};

class FrameCheck {
 public:
  static constexpr int kBlankRange = 4;              // grey levels
  static constexpr double kExposureJumpRatio = 2.0;  // mean ratio (either direction)
  static constexpr double kExposureMinMean = 8.0;    // darker means are not compared

  FrameCheckResult check(const Frame& f);

 private:
  bool have_first_ = false;
  int width_ = 0, height_ = 0;
  int64_t last_stamp_ns_ = 0;
  double last_mean_ = -1.0;  // of the last non-blank accepted frame; < 0: none yet
};

}  // namespace rdslam
