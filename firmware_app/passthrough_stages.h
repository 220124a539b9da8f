// The stand-in tracker and mapper that `rdslam run` uses until the SLAM core lands
// (issue 9: "start with a pass-through tracker and replace it"). They exercise the whole
// runtime contract of core/stages.h without estimating anything:
// - PassthroughTracker reports the source's ground-truth pose for each frame (nearest
//   ground-truth stamp within `max_stamp_gap_ns`, state TRACKING), or the identity in
//   INITIALIZING when there is no ground truth for it; every `keyframe_every`-th tracked
//   frame is handed to the mapper through an SPSC ring, like a real keyframe decision.
// - PassthroughMapper takes those keyframes in step() (waiting on a doorbell, never
//   sleep-polling) and keeps their poses in a preallocated array; the tracker reports the
//   count as TrackResult::keyframes.
// Nothing is allocated after construction. Covariance is unknown (all -1), quality 0,
// inliers 0: a consumer can tell these poses were not estimated.
//
// Ownership: PassthroughStages owns both stages and the ring between them. Threads: the
// tracker thread calls tracker().track(), the mapper thread mapper().step().
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/spsc_ring.h"
#include "core/stages.h"
#include "core/trajectory.h"

namespace rdslam {

struct PassthroughParams {
  int keyframe_every = 10;             // every N-th tracked frame goes to the mapper
  int max_keyframes = 4096;            // mapper's preallocated keyframe store
  int64_t max_stamp_gap_ns = 5000000;  // ground truth farther than this: no pose
};

class PassthroughStages {
 public:
  PassthroughStages(std::optional<Trajectory> ground_truth, const PassthroughParams& params = {});
  PassthroughStages(const PassthroughStages&) = delete;
  PassthroughStages& operator=(const PassthroughStages&) = delete;

  TrackerStage& tracker() { return tracker_; }
  MapperStage& mapper() { return mapper_; }

  // Keyframes the mapper has stored (any thread).
  int keyframes() const { return keyframes_.load(std::memory_order_acquire); }
  // Keyframes lost because the mapper ring or store was full (any thread).
  uint64_t keyframes_dropped() const { return kf_dropped_.load(std::memory_order_relaxed); }

 private:
  struct Keyframe {
    uint64_t seq = 0;
    StampedPose pose;
  };

  class Tracker : public TrackerStage {
   public:
    explicit Tracker(PassthroughStages& owner) : owner_(owner) {}
    TrackResult track(const Frame& frame) override;

   private:
    PassthroughStages& owner_;
    uint64_t tracked_ = 0;
  };
  class Mapper : public MapperStage {
   public:
    explicit Mapper(PassthroughStages& owner) : owner_(owner) {}
    bool step(int timeout_ms) override;

   private:
    PassthroughStages& owner_;
  };

  // Index of the ground-truth pose nearest to `stamp_ns`, or -1 if none within the gap.
  long nearest(int64_t stamp_ns) const;

  const PassthroughParams params_;
  Trajectory gt_;  // sorted by stamp
  SpscRing<Keyframe> kf_ring_;
  Doorbell kf_bell_;
  std::vector<Keyframe> kf_store_;  // mapper thread; reserved up front
  std::atomic<int> keyframes_{0};
  std::atomic<uint64_t> kf_dropped_{0};
  Tracker tracker_;
  Mapper mapper_;
};

}  // namespace rdslam
