// The contract between the runtime (firmware_app/pipeline: threads, rings, LCM) and the
// SLAM algorithms (core/). core/ never creates threads: the pipeline owns one tracker thread
// that calls TrackerStage::track() for each frame it takes from the capture ring, and one
// mapper thread that calls MapperStage::step() in a loop. Tracker and mapper exchange data
// only through SPSC rings and immutable snapshots that they create together
// (make_slam_stages() in the SLAM module); the pipeline never sees their internals.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>

#include "core/geometry.h"

namespace rdslam {

struct Frame;          // core/frame_source.h
class DebugFrameSink;  // core/debug_frame.h

// Values match the STATE_* constants of lcmtypes/rdslam_pose_t.lcm.
enum class TrackingState : int8_t {
  kInitializing = 0,  // no map yet; pose is meaningless
  kTracking = 1,      // pose supported by the estimator
  kLost = 2,          // tracking failed; pose is the last good one
  kRelocalized = 3,   // first pose after relocalization
};

const char* to_string(TrackingState s);

struct TrackResult {
  TrackingState state = TrackingState::kInitializing;
  Eigen::Vector3d p_world_cam{0, 0, 0};        // camera centre in the map frame
  Eigen::Quaterniond q_world_cam{1, 0, 0, 0};  // rotation camera -> world
  int inliers = 0;
  double quality = 0.0;  // inlier ratio in [0, 1]
  // Row-major 6x6 covariance of the error [dc, dtheta] of (p_world_cam, q_world_cam): camera
  // centre in world (map units), rotation vector of camera -> world in the world frame (rad),
  // from the final eq. (1) refinement (core/pose_refine.h PoseInformation); all -1 unless the
  // state is TRACKING / RELOCALIZED (lcmtypes/rdslam_pose_t.lcm).
  std::array<double, 36> covariance{};
  int map_points = 0;              // valid map points (for status)
  int keyframes = 0;               // valid keyframes (for status)
  int64_t invalidated_points = 0;  // cumulative
  double mapper_wait_ms = 0.0;     // time track() blocked on the mapper (tracker.sync_mapper only)
  // The reference keyframe (the one sharing most of this frame's tracked points) of map epoch
  // `epoch`, and the frame's pose relative to it when tracked (camera -> reference keyframe);
  // -1 when the frame has none (not tracked, no keyframes yet). Evaluation re-anchors the
  // frame on the keyframe's final pose (MapperStage::final_keyframe_pose).
  // `epoch` is the map's identity (rdslam.pose_t map_epoch): a new number at every map reset,
  // after which the world frame and scale are the new map's; an earlier map's number again
  // when the tracker relocalizes into a kept earlier map or the current map is merged into it
  // (then the poses continue in that map's frame).
  int ref_keyframe = -1;
  uint32_t epoch = 0;
  Eigen::Quaterniond q_ref_cam{1, 0, 0, 0};
  Eigen::Vector3d p_ref_cam{0, 0, 0};
  // Recovery: maps merged into earlier ones so far (cumulative; docs/slam.md "Recovery").
  int map_merges = 0;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// Called by the tracker thread only. Must not allocate on the heap after warm-up.
class TrackerStage {
 public:
  virtual ~TrackerStage() = default;
  virtual TrackResult track(const Frame& frame) = 0;
  // Opt-in debug output (core/debug_frame.h): after this call every track() also hands a
  // DebugFrame to `sink` (nullptr: off again). Call before the first track(), from the
  // thread that owns the stage. Returns false if the stage has no debug output.
  virtual bool set_debug_sink(DebugFrameSink* /*sink*/) { return false; }
};

// Called by the mapper thread only. step() does one unit of work (e.g. one keyframe
// insertion or one local bundle adjustment) or waits at most `timeout_ms` for work; it
// returns false when there was nothing to do.
class MapperStage {
 public:
  virtual ~MapperStage() = default;
  virtual bool step(int timeout_ms) = 0;
  // Final trajectory (evaluation; core/mapper.h set_keep_trail): call before the first
  // step(). Stages without a map ignore it.
  virtual void set_keep_trail(bool /*on*/) {}
  // After the last step(): the final pose (T_world_cam) of a frame tracked with `r`,
  // re-anchored on its reference keyframe in the final map (core/mapper.h final_frame_pose),
  // or false (no map, keyframe not in it). Stages without a map return false.
  virtual bool final_frame_pose(const TrackResult& /*r*/, Pose* /*T_world_cam*/) const {
    return false;
  }
  // After the last step(): one line on the work done (keyframes mapped, local BAs that
  // yielded to a waiting keyframe); empty for stages without a map.
  virtual std::string summary() const { return {}; }
  // Saves the map to `path` (core/map_io.h; atomic, `keep` - 1 older versions kept) from the
  // calling thread: the mapper thread, or any thread while the mapper thread is not running
  // (after the last step()). False with *message set when there is no map to save or the
  // write failed; true with a one-line summary in *message.
  virtual bool save_map(const std::string& /*path*/, int /*keep*/, std::string* message) {
    if (message) *message = "this pipeline has no map";
    return false;
  }
};

}  // namespace rdslam
