// Messages from the tracker to the mapper (Sec. 4's "potential keyframes"), carried in a
// preallocated SPSC ring (core/spsc_ring.h): the tracker fills a slot in place (no heap
// allocation once the slot's buffers have grown), the mapper reads it in place.
//
// Ownership: slots live in the ring (SlamLink). Threads: the tracker writes a slot between
// back() and commit(); the mapper reads it between front() and pop().
#pragma once

#include <atomic>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "core/features.h"
#include "core/geometry.h"
#include "core/initializer.h"
#include "core/match_index.h"
#include "core/spsc_ring.h"

namespace rdslam {

struct KeyframeCandidate {
  enum class Kind : uint8_t { kKeyframe, kInit, kReset };
  Kind kind = Kind::kKeyframe;
  uint32_t epoch = 0;  // map epoch (incremented by each reset)
  int64_t stamp_ns = 0;
  Pose T_cam_world;
  Features features;
  std::vector<int64_t> point_of;  // per feature: tracked map point id or -1
  cv::Mat image;                  // the frame (grey or BGR) for appearance tests (Sec. 4)
  // kInit only: the reference frame and the initial points (ids 0..n-1).
  Features features0;
  int64_t stamp0_ns = 0;
  cv::Mat image0;
  std::vector<InitPoint, Eigen::aligned_allocator<InitPoint>> init_points;
};

// What tracker and mapper share (created by make_slam_stages): the candidate ring, the
// doorbell the mapper sleeps on, and the double-buffered matching index.
struct SlamLink {
  explicit SlamLink(uint32_t ring_capacity) : candidates(ring_capacity) {}
  SpscRing<KeyframeCandidate> candidates;
  Doorbell bell;    // tracker -> mapper: a candidate was queued
  Doorbell mapped;  // mapper -> tracker: a candidate was processed (sync mode only)
  MatchIndex index;
  std::atomic<int> mapper_busy{0};  // 1 while the mapper processes a candidate
  std::atomic<int> keyframes{0}, points{0};
  std::atomic<int64_t> invalidated_points{0};
  // Debug output (core/debug_frame.h): > 0 makes the mapper list this many recently
  // invalidated points in each snapshot (MapSnapshot::invalid_*). Set before the run.
  std::atomic<int> debug_recent_invalid{0};
};

}  // namespace rdslam
