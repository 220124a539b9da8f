// The SLAM system as two pipeline stages (core/stages.h) plus a deterministic single-thread
// driver.
//
// make_slam_stages() builds the Tracker (tracker thread) and the Mapper (mapper thread); they
// share only a SlamLink: an SPSC ring of preallocated keyframe candidates (tracker -> mapper)
// and the double-buffered matching index (mapper -> tracker, one atomic pointer swap). The
// mapper therefore never blocks the tracker for longer than that swap.
//
// run_offline() alternates tracker and mapper in the calling thread: after each frame the
// mapper processes every pending candidate. Results are deterministic (the callgrind mode of
// issue 10 and the accuracy tests use it).
//
// Ownership: SlamStages owns both stages. Threads: see each stage.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/change_detection.h"
#include "core/features.h"
#include "core/frame_source.h"
#include "core/mapper.h"
#include "core/stages.h"
#include "core/tracker.h"
#include "core/trajectory.h"

namespace rdslam {

struct SlamParams {
  FeatureParams features;
  TrackerParams tracker;
  MapperParams mapper;
  ParsacParams parsac;  // config section `parsac` (core/parsac.h), copied in by the caller
  ChangeDetectionParams dynamic;  // config section `dynamic`: Sec. 4 updating in the mapper
  // Cross-section checks; empty when valid.
  std::string validate() const;
};

struct SlamStages {
  std::unique_ptr<TrackerStage> tracker;
  std::unique_ptr<MapperStage> mapper;
  // What they share; firmware_app uses its command fields (localize_only, save_requests,
  // reset_requests: core/keyframe.h) while the pipeline runs.
  std::shared_ptr<SlamLink> link;
};

// A map to start from (core/map_io.h): the mapper loads it before the first step() and the
// tracker starts LOST, relocalizing in it; `localize_only` freezes it (SlamLink::localize_only).
// `save_path` (optional): where the mapper saves on a save request, keeping `save_keep` versions.
struct SlamStart {
  Map* prior = nullptr;  // moved from
  bool localize_only = false;
  std::string save_path;
  int save_keep = 1;
  // Saves requested while running are encoded and written by this writer's thread (not
  // owned; outlives the stages' threads); nullptr: on the mapper thread (core/mapper.h).
  MapSaveWriter* save_writer = nullptr;
};

// The link between a tracker and a mapper (core/keyframe.h); in ORB mode with the place
// recognition vocabulary loaded (tracker.reloc_vocabulary; throws std::runtime_error naming the
// file when it is missing or corrupt).
std::shared_ptr<SlamLink> make_slam_link(const SlamParams& params, uint32_t ring_capacity);

SlamStages make_slam_stages(const SlamParams& params, const CameraModel& camera,
                            const SlamStart& start = {});

struct OfflineFrame {
  int64_t stamp_ns = 0;
  uint64_t seq = 0;
  TrackResult result;
  double track_ms = 0.0;      // tracker wall time for this frame
  double track_cpu_ms = 0.0;  // tracker thread CPU time (robust to a loaded machine)
  double mapper_ms = 0.0;     // mapper time spent after this frame
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct OfflineRun {
  std::vector<OfflineFrame, Eigen::aligned_allocator<OfflineFrame>> frames;
  MapperStats mapper;
  TrackerStats tracker;
  int final_keyframes = 0, final_points = 0;
  // The final trajectory (as the replay's, firmware_app/pipeline.h replay_trajectory): every
  // tracked frame re-anchored on its reference keyframe's pose in the final map, through the
  // merges of its map epoch (recovery); frames whose keyframe is gone keep their online pose.
  Trajectory final_trajectory;
};

// Reads `source` to the end (or `max_frames`, 0 = all) through tracker and mapper in this
// thread. `on_frame` (optional) sees every result as it is produced.
OfflineRun run_offline(FrameSource& source, const SlamParams& params, const CameraModel& camera,
                       int max_frames = 0,
                       const std::function<void(const OfflineFrame&)>& on_frame = nullptr);

}  // namespace rdslam
