// The matching index of Sec. 3: the reference features (valid 3D points with descriptors)
// that the tracker matches every frame against, double-buffered as in the paper ("one KD-tree
// active for real-time matching, the other waiting for updating").
//
// The mapper builds a complete immutable MapSnapshot (flat arrays of point positions,
// normals, descriptors, observing keyframes, keyframe poses, and in SIFT mode the FLANN
// KD-tree of the descriptors) in its own thread, and publishes it with one atomic pointer
// swap. The tracker picks up the newest snapshot at the start of a frame; the snapshot it is
// using is never modified. Retired snapshots are freed by the mapper, never by the tracker,
// so the tracker does not free memory on the heap either.
//
// Ownership: MatchIndex is shared by the two stages (make_slam_stages). Threads: publish()
// and collect() from the mapper thread; acquire() from the tracker thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/flann.hpp>
#include <unordered_map>
#include <vector>

#include "core/geometry.h"
#include "core/keyframe_database.h"

namespace rdslam {

struct MapSnapshot {
  uint64_t version = 0;
  uint32_t epoch = 0;  // map epoch: a reset starts a new map
  bool binary = true;
  // Points (valid reference features only), row-aligned.
  std::vector<int64_t> ids;
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> p_world;
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> normal;
  std::vector<float> min_dist, max_dist;
  cv::Mat desc;  // one row per point
  // Observing keyframes of each point (CSR): obs_kf[obs_start[i] .. obs_start[i+1]) are
  // indices into kf_ids.
  std::vector<int> obs_start, obs_kf;
  // Keyframes.
  std::vector<int> kf_ids;
  std::vector<Pose, Eigen::aligned_allocator<Pose>> kf_pose;  // T_cam_world
  std::vector<int> kf_points;  // well-observed points of each keyframe (>= 3 views)
  // Points of each keyframe (CSR, the inverse of obs_*): rows
  // kf_rows[kf_row_start[k] .. kf_row_start[k+1]) are observed by keyframe kf_ids[k].
  std::vector<int> kf_row_start, kf_rows;
  // Place recognition (ORB with a vocabulary): the keyframe database of this map
  // (core/keyframe_database.h), shared by the snapshots published while no keyframe changed.
  std::shared_ptr<const KeyframeDatabase> places;
  std::unordered_map<int64_t, int> row_of;  // point id -> row
  // SIFT mode: the paper's KD-tree over `desc` (FLANN, 4 randomised trees).
  std::unique_ptr<cv::flann::Index> kdtree;
  // Debug output only (core/debug_frame.h; empty unless SlamLink::debug_recent_invalid > 0):
  // the most recently invalidated points (V(X) = 0 by map updating), oldest first, at most
  // debug_recent_invalid of them; positions as when they were invalidated.
  std::vector<int64_t> invalid_ids;
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> invalid_p_world;
  // Recovery (docs/slam.md, "Recovery"): the frozen earlier maps (epochs) the mapper keeps,
  // each as its last snapshot (with the keyframe database of its freeze), for relocalization
  // of a LOST or re-initializing tracker into an earlier map; oldest first.
  std::vector<std::shared_ptr<const MapSnapshot>> kept;
  // The last merge into this map (core/map_merge.h), repeated by every later snapshot of it:
  // the map of epoch `merged_from` (-1: none) was moved into this one by x' = s R x + t
  // (merge_scale, merge_R, merge_t) with its point ids shifted by merge_point_offset. A tracker
  // still in epoch merged_from follows it (Tracker::follow_merge).
  int64_t merged_from = -1;
  double merge_scale = 1.0;
  Eigen::Matrix3d merge_R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d merge_t = Eigen::Vector3d::Zero();
  int64_t merge_point_offset = 0;

  int rows() const { return static_cast<int>(ids.size()); }
  int find(int64_t id) const {
    auto it = row_of.find(id);
    return it == row_of.end() ? -1 : it->second;
  }
};

class MatchIndex {
 public:
  // Mapper: make `snap` the active index (one atomic index store). Never blocks.
  void publish(std::shared_ptr<const MapSnapshot> snap);
  // Tracker: the active snapshot (nullptr before the first publish). Holds a reference.
  // Lock-free: a retry loop that only repeats while publish() runs concurrently.
  std::shared_ptr<const MapSnapshot> acquire() const;
  uint64_t version() const { return version_.load(std::memory_order_acquire); }
  // Mapper: free retired snapshots that the tracker (or a debug sink) no longer holds.
  void collect();

 private:
  // No lock between the tracker and the mapper (a SCHED_FIFO tracker waiting on a niced
  // mapper's mutex would be a priority inversion; std::atomic<shared_ptr> is C++20, and
  // libstdc++'s atomic_load(shared_ptr) takes a mutex from a pool). Instead: three slots
  // written only by the mapper, the active slot's index published atomically, and one hazard
  // index through which the tracker announces the slot it is copying from. publish() writes
  // a slot that is neither active nor announced; acquire() re-reads the active index after
  // announcing, so it never copies a slot that publish() may be writing (all four accesses
  // seq_cst). A slot's previous snapshot moves to `retired_`, which only the mapper touches.
  static constexpr int kSlots = 3;
  std::shared_ptr<const MapSnapshot> slots_[kSlots];
  std::atomic<int> active_{-1};
  mutable std::atomic<int> reading_{-1};
  std::atomic<uint64_t> version_{0};
  std::vector<std::shared_ptr<const MapSnapshot>> retired_;  // mapper thread only
};

}  // namespace rdslam
