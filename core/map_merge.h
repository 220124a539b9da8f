// Map merging after recovery (docs/slam.md, "Recovery: map epochs and merges"): a similarity
// transform (Sim(3): scale, rotation, translation) between two monocular maps, estimated from
// 3D-3D point pairs by RANSAC over Umeyama's closed form (Eigen::umeyama with scale), checked by
// reprojection in both keyframes, and the merge of one map into the other under it.
//
// Used by the mapper (core/mapper.h) when a keyframe of the current map epoch is recognized in a
// kept earlier map: the current map's keyframes and points are transformed into the earlier
// map's frame, re-numbered after the earlier map's ids (constant offsets, so the tracker can
// follow with one addition) and inserted; duplicate points are fused.
//
// Ownership: pure functions on the caller's data. Threads: mapper thread. Allocates (a merge is
// rare and runs on the mapper thread, never on the tracker's real-time path).
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry.h"
#include "core/map.h"

namespace rdslam {

// x_target = s R x_source + t.
struct Sim3 {
  double s = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return s * (R * p) + t; }
  Sim3 inverse() const;
  // A camera pose T_cam_world of the source frame as a pose of the target frame (camera
  // coordinates scaled by s, which leaves every projection unchanged).
  Pose camera(const Pose& T_cam_source) const;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// One putative correspondence between keyframe A (source map) and keyframe B (target map): the
// two points and the features that observe them (undistorted pixels, noise scales).
struct Sim3Pair {
  Eigen::Vector3d a, b;
  Eigen::Vector2d xa, xb;
  double sa = 1.0, sb = 1.0;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct Sim3RansacParams {
  int iterations = 300;
  int min_inliers = 20;
  double chi2 = 9.21;  // squared reprojection error / scale^2 (2 DoF, 99%), in both keyframes
  uint32_t seed = 1;   // deterministic sampling
};

// RANSAC over minimal samples of 3 pairs, then Umeyama on all inliers (twice). Writes the
// inlier flags and returns the inlier count (0 and *S untouched when below min_inliers).
// Ta / Tb: T_cam_world of A in the source frame and of B in the target frame.
int estimate_sim3(const std::vector<Sim3Pair, Eigen::aligned_allocator<Sim3Pair>>& pairs,
                  const Pose& Ta, const Pose& Tb, const PinholeIntrinsics& K,
                  const Sim3RansacParams& p, Sim3* S, std::vector<uint8_t>* inliers);

// Umeyama with scale on the given pairs (b = S a); false when degenerate.
bool umeyama_sim3(const std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>& a,
                  const std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>& b,
                  Sim3* S);

// Moves every keyframe and point of `source` into `target` under S, with ids shifted by
// target's next ids (returned in *kf_offset / *point_offset), then fuses each (source point id,
// target point id) pair of `fuse` (source ids before the shift): the source point's
// observations move to the target point (where its keyframe does not see it already) and the
// source point goes. Source keyframes lose their `fixed` flag (the target keeps its gauge).
// Returns the number of points fused.
int merge_maps(Map& target, Map&& source, const Sim3& S,
               const std::vector<std::pair<int64_t, int64_t>>& fuse, int* kf_offset,
               int64_t* point_offset);

}  // namespace rdslam
