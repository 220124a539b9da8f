// Messages from the tracker to the mapper (Sec. 4's "potential keyframes"), carried in a
// preallocated SPSC ring (core/spsc_ring.h): the tracker fills a slot in place (no heap
// allocation once the slot's buffers have grown), the mapper reads it in place.
//
// A second ring carries "frame observations" of ordinary tracked frames for Sec. 4's per-frame
// map updating (core/map_updater.h): the tracker fills one every `observe_every_n` tracked
// frames (SlamLink::observe_every_n, from dynamic.check_every_n_frames); when the ring is full
// the observation is skipped and counted (the mapper is behind: the next one is newer anyway).
//
// Ownership: slots live in the rings (SlamLink). Threads: the tracker writes a slot between
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
#include "core/vocabulary.h"

namespace rdslam {

struct KeyframeCandidate {
  enum class Kind : uint8_t { kKeyframe, kInit, kReset };
  Kind kind = Kind::kKeyframe;
  uint32_t epoch = 0;  // map epoch (a new one at each reset; an earlier one after a merge)
  int64_t stamp_ns = 0;
  int64_t frame_no = 0;  // the tracker's frame counter at this frame (kInit: the second frame)
  Pose T_cam_world;
  Features features;
  std::vector<int64_t> point_of;  // per feature: tracked map point id or -1
  cv::Mat image;                  // the frame (grey or BGR) for appearance tests (Sec. 4)
  // kInit only: the reference frame and the initial points (ids 0..n-1).
  Features features0;
  int64_t stamp0_ns = 0;
  int64_t frame_no0 = 0;  // the reference frame's counter
  cv::Mat image0;
  std::vector<InitPoint, Eigen::aligned_allocator<InitPoint>> init_points;
  int levels = 0;  // kInit: pyramid levels of the new map's features (0: features.levels)
};

// One tracked frame for the updater: only the tracked features are carried (their undistorted
// pixels and map point ids), plus the ids the robust estimator (PARSAC) rejected in this frame
// (matched but inconsistent with the camera motion: the second paper's "moved" event).
// Buffers grow once to the feature cap and are reused (no allocation after warm-up).
struct FrameObservation {
  uint32_t epoch = 0;
  int64_t stamp_ns = 0;
  int64_t frame_no = 0;  // tracker's tracked-frame counter (gaps between observations)
  Pose T_cam_world;
  cv::Mat image;  // the frame (grey or BGR), as the keyframe images
  int tracked = 0;
  std::vector<cv::Point2f> un;    // [tracked] undistorted pixels of the tracked features
  std::vector<int64_t> point_of;  // [tracked] their map point ids
  int rejected = 0;
  std::vector<int64_t> rejected_ids;  // [rejected] PARSAC outliers of this frame
};

// What tracker and mapper share (created by make_slam_stages): the candidate ring, the
// doorbell the mapper sleeps on, and the double-buffered matching index.
struct SlamLink {
  explicit SlamLink(uint32_t ring_capacity, int observe_every = 0)
      : candidates(ring_capacity), observations(2), observe_every_n(observe_every) {}
  SpscRing<KeyframeCandidate> candidates;
  // Frame observations (two slots: one being processed, one waiting). Set at construction.
  SpscRing<FrameObservation> observations;
  const int observe_every_n;  // 0: no observations (map updating off)
  std::atomic<int64_t> observations_sent{0}, observations_skipped{0};
  Doorbell bell;    // tracker -> mapper: a candidate was queued
  Doorbell mapped;  // mapper -> tracker: a candidate was processed (sync mode only)
  MatchIndex index;
  // Place recognition (core/keyframe_database.h, core/relocalizer.h): the ORB vocabulary the
  // mapper describes keyframes with and the tracker describes LOST frames with; immutable, set
  // before the stages are built (null: relocalization matches against every map point).
  std::shared_ptr<const Vocabulary> vocabulary;
  std::atomic<int> mapper_busy{0};  // 1 while the mapper processes a candidate/observation
  std::atomic<int> keyframes{0}, points{0};
  std::atomic<int64_t> invalidated_points{0};
  std::atomic<int> merges{0};  // recovery: maps merged into earlier ones (core/map_merge.h)
  // Debug output (core/debug_frame.h): > 0 makes the mapper list this many recently
  // invalidated points in each snapshot (MapSnapshot::invalid_*). Set before the run.
  std::atomic<int> debug_recent_invalid{0};
  // Prior maps and run-time commands (issue 24; set by firmware_app from any thread):
  // localize_only freezes the map (the tracker proposes no keyframes and sends no observations,
  // the mapper ignores any that are queued); each increment of save_requests makes the mapper
  // save its map at its next step (Mapper::set_save_target), counted in saves_done /
  // saves_failed; each increment of reset_requests makes the tracker start a new map epoch and
  // initialize again.
  std::atomic<bool> localize_only{false};
  std::atomic<uint32_t> save_requests{0}, saves_done{0}, saves_failed{0};
  std::atomic<uint32_t> reset_requests{0};
  // Save requests served by a save that was already due (requests made while a save was in
  // progress, or several between two mapper steps): one map file for all of them.
  std::atomic<uint32_t> saves_coalesced{0};
};

}  // namespace rdslam
