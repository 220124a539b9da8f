// Opt-in per-frame debug record of the tracker, for `rdslam replay --debug-video/--debug-images`
// (firmware_app/debug_video.h draws it): what the tracker decided on one frame, enough to
// draw it like the paper's Figures 4, 9 and 10 (inliers, outliers of the robust estimator,
// valid map points, points invalidated by map updating).
//
// Off by default and free when off: the tracker fills and emits a DebugFrame only after
// TrackerStage::set_debug_sink() gave it a sink; without one it does no extra work and no
// allocation. When on, each record allocates (an image copy, the feature list) on the
// tracker thread, unless the sink recycles its own records (recycles_records(): the live
// viewer publisher, firmware_app/viewer_publisher.h): then the tracker fills a record the
// sink lends it, in place, only for the frames the sink asks for, and allocates nothing once
// the sink's records have the frame's size.
//
// Ownership: the record owns its image and feature list and shares (read-only) the
// MapSnapshot the tracker matched against, so a sink may keep it and draw on another thread.
// The snapshot is still freed by the mapper (MatchIndex::collect) once nobody holds it.
// Threads: on_debug_frame() is called on the tracker thread, once per frame, in order.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "core/frame_source.h"
#include "core/geometry.h"
#include "core/match_index.h"
#include "core/stages.h"

namespace rdslam {

enum class DebugFeatureKind : uint8_t {
  kUnmatched = 0,       // no map point
  kInlier = 1,          // supports the published pose
  kRejectedRobust = 2,  // matched, rejected by the robust estimator (parsac.method)
  kRejectedRefine = 3,  // matched, rejected by the eq. (1) refinement
  kUnsupported = 4,     // matched, but too few matches for a pose (the frame is LOST)
};

const char* to_string(DebugFeatureKind k);

struct DebugFeature {
  float x = 0.f, y = 0.f;  // raw pixel coordinates (Features::kps)
  DebugFeatureKind kind = DebugFeatureKind::kUnmatched;
};

struct DebugFrame {
  uint64_t seq = 0;
  int64_t stamp_ns = 0;
  int64_t dataset_index = -1;
  TrackResult result;
  // The pose the map points are projected with: this frame's estimate, or while LOST the last
  // good one. False while INITIALIZING (no map).
  bool has_pose = false;
  Pose T_cam_world;
  cv::Mat image;  // the frame as captured (grey or BGR), a private copy
  std::vector<DebugFeature> features;
  // The tracker's matching index this frame (valid points; MapSnapshot::invalid_* lists the
  // recently invalidated ones). May be null (before the first map).
  std::shared_ptr<const MapSnapshot> snapshot;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// Number of features of kind `k` in `d`.
int count_features(const DebugFrame& d, DebugFeatureKind k);

class DebugFrameSink {
 public:
  virtual ~DebugFrameSink() = default;
  // Tracker thread, after track() returned for this frame. May block (lossless replay) or
  // drop the record; must not call back into the tracker.
  virtual void on_debug_frame(DebugFrame&& frame) = 0;

  // Recycling sinks (true, constant for the sink's life): instead of on_debug_frame(), the
  // tracker calls acquire_record() once per frame; a null result skips the frame (not wanted
  // now, or no free record), otherwise the tracker overwrites every field of the record in
  // place (image with copyTo, features with resize: no allocation once they have the size
  // and capacity) and hands it back with submit_record(). Tracker thread; neither may block.
  virtual bool recycles_records() const { return false; }
  virtual DebugFrame* acquire_record(const Frame& /*frame*/) { return nullptr; }
  virtual void submit_record(DebugFrame* /*record*/) {}
};

}  // namespace rdslam
