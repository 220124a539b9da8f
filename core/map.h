// The SLAM map: keyframes and 3D points (the paper's reference features, Sec. 3-4), with
// the per-point and per-keyframe state that the dynamic-environment updating of Sec. 4
// (Algorithm 1) needs: V(X) validity, observation lists, the keyframe where each point first
// appeared, miss/move counters (second paper), and a per-keyframe validity flag.
//
// The map is bounded: MapperParams caps keyframes and points, and the mapper's culling steps
// (core/mapper.h: recent points, redundant keyframes, caps) enforce them (docs/slam.md).
//
// Ownership: the mapper owns the Map; nobody else touches it. The tracker sees immutable
// MapSnapshots (core/match_index.h). Threads: mapper thread only.
#pragma once

#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <unordered_map>
#include <vector>

#include "core/features.h"
#include "core/geometry.h"

namespace rdslam {

struct Observation {
  int kf = -1;    // keyframe id
  int feat = -1;  // feature index in that keyframe
};

struct MapPoint {
  int64_t id = -1;
  Eigen::Vector3d p_world{0, 0, 0};
  std::vector<uint8_t> desc;  // representative descriptor (Features::desc row bytes)
  std::vector<Observation> obs;
  int first_kf = -1;                // keyframe where the point first appeared (Alg. 1, x_p)
  int created_kf_seq = 0;           // mapper keyframe counter at creation (recent-point culling)
  bool valid = true;                // V(X) of Sec. 4: invalid points leave the matching index
  Eigen::Vector3d normal{0, 0, 1};  // mean viewing direction (point -> camera)
  float min_dist = 0.f, max_dist = 1e9f;  // scale-invariance distance range (ORB levels)
  int missed = 0, moved = 0;              // second paper's counters (dynamic module)
  int unmatched = 0;  // consecutive checks in view and unchanged but not tracked (pruning)
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct Keyframe {
  int id = -1;
  int64_t stamp_ns = 0;
  int64_t frame_no = 0;  // the tracker's frame counter (KeyframeCandidate::frame_no)
  Pose T_cam_world;
  Features features;
  std::vector<int64_t> point_of;  // per feature: map point id or -1
  bool valid = true;              // Sec. 4: invalid keyframes are replaced
  cv::Mat image;                  // the frame as captured (appearance tests of Sec. 4)
  bool fixed = false;             // gauge keyframe (never moved by bundle adjustment)
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

class Map {
 public:
  std::map<int, Keyframe> keyframes;
  std::unordered_map<int64_t, MapPoint> points;

  int64_t next_point_id = 0;
  int next_kf_id = 0;
  int kf_seq = 0;  // keyframes ever inserted

  MapPoint* point(int64_t id);
  Keyframe* keyframe(int id);
  // Adds an observation to both sides; false if the feature already has a point.
  bool add_observation(int64_t pid, int kf, int feat);
  void remove_observation(int64_t pid, int kf);
  void erase_point(int64_t pid);
  void erase_keyframe(int kf);
  // Keyframes sharing points with `kf`, as (shared count, id), most shared first.
  std::vector<std::pair<int, int>> covisible(int kf, int min_shared = 1) const;
  // Recomputes the normal and distance range from the observations.
  void update_point_geometry(MapPoint& p, float scale_factor, int levels) const;
  int count_valid_points() const;
  // Sec. 4's 90% rule, counted once for the mapper's culling and the map updater's keyframe
  // check (core/mapper.h, core/map_updater.h).
  struct Redundancy {
    int redundant = 0;  // points invalid (V(X) = 0) or seen by >= 3 other keyframes
    int total = 0;      // features of the keyframe with a map point
    // "larger than 90% of its total point number" (fraction = mapper.redundant_fraction)
    bool exceeds(double fraction) const { return total > 0 && redundant > fraction * total; }
  };
  Redundancy redundancy(const Keyframe& kf) const;
};

}  // namespace rdslam
