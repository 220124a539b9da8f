// Camera pose from 2D-3D correspondences for the tracker: the paper's eq. (1),
//   min_{R,t} sum_i || x_i - pi(K (R X_i + t)) ||^2,
// solved by Gauss-Newton on SE(3) with a Huber kernel and chi-square outlier classification
// (several rounds, re-classifying each round), plus a minimal-sample robust estimator for
// when no pose prior exists (relocalization).
//
// The robust estimator is an adapter over core/parsac.h (the paper's PARSAC, Sec. 5, or its
// baselines by `parsac.method`), followed by the eq. (1) refinement with per-feature noise.
//
// Ownership: PoseEstimator owns its scratch buffers, sized at construction.
// Threads: one instance per thread (the tracker owns one).
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry.h"
#include "core/parsac.h"

namespace rdslam {

struct PoseRefineStats {
  int inliers = 0;
  double rms_px = 0.0;  // over inliers
};

// Inlier gate of refine_pose: a squared normalised error above it (chi-square 2 DoF, 95%) is an
// outlier.
constexpr double kInlierChi2 = 5.991;

// Eq. (1) with robust weights. `sigma_px[i]` is the measurement standard deviation of
// observation i (pixels, grows with the pyramid level). Observations whose squared normalised
// error exceeds 5.991 (chi-square 2 DoF, 95%) are classified outliers in `inlier[i]` (0/1);
// outliers are excluded from the next round. With `keep_initial_inliers`, the first round
// uses only the observations already marked 1 in `inlier` (a robust estimator's consensus
// set), so observations it rejected cannot pull the pose before they are re-classified.
// Does not allocate.
PoseRefineStats refine_pose(const PinholeIntrinsics& K, const Eigen::Vector3d* p_world,
                            const Eigen::Vector2d* obs, const float* sigma_px, int n,
                            Pose& T_cam_world, uint8_t* inlier, int rounds = 4, int iterations = 10,
                            bool keep_initial_inliers = false);

class PoseEstimator {
 public:
  PoseEstimator(const ParsacParams& params, const CameraModel& camera, int max_correspondences);
  // Robust pose (minimal samples, then eq. (1)). `guess` (optional) is the motion-model
  // prediction. Returns the inlier count (0 on failure). Does not allocate (parsac, arsac,
  // ransac, lo-ransac).
  int estimate(const Eigen::Vector3d* p_world, const Eigen::Vector2d* obs, const float* sigma_px,
               int n, Pose& T_cam_world, uint8_t* inlier, const Pose* guess = nullptr);
  void reset_prior() { robust_.reset_prior(); }

 private:
  PinholeIntrinsics K_;
  int max_n_;
  RobustPoseEstimator robust_;
};

}  // namespace rdslam
