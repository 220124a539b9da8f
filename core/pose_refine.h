// Camera pose refinement by minimising the reprojection error of eq. (1) of RDSLAM (Tan et al.,
// ISMAR 2013): min_{R,T} sum_i || x_i - pi(K (R X_i + T)) ||^2 over the inliers.
//
// A fixed-size Levenberg-Marquardt in Eigen (6x6 normal equations, left-multiplicative
// update on SE(3)): no heap allocation, so the tracker can call it every frame; Ceres stays in
// the mapper's bundle adjustment.
//
// PoseInformation: the covariance of a refined pose (rdslam.pose_t's covariance), from the
// Gauss-Newton information of eq. (1) at the final pose over its inliers; fixed-size Eigen, no
// heap allocation, so the tracker computes it for every published pose.
//
// Ownership: free functions over caller-owned arrays; PoseInformation is a value type.
// Threads: any; no shared state.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "core/geometry.h"
#include "core/pose_solvers.h"

namespace rdslam {

struct RefineResult {
  int iterations = 0;         // LM iterations run
  int used_points = 0;        // points in the sum (mask set, finite, in front of the camera)
  double initial_cost = 0.0;  // sum of squared pixel errors before refinement
  double final_cost = 0.0;    // ... and after
  bool converged = false;     // step below tolerance before max_iterations
};

// Refines (R_cam_world, t_cam_world) in place over the points whose mask byte is non-zero
// (all points when mask is null). Needs >= 3 used points; otherwise leaves the pose unchanged.
RefineResult refine_pose(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world,
                         const uint8_t* mask, int count, const Intrinsics& K, int max_iterations,
                         Eigen::Matrix3d* R_cam_world, Eigen::Vector3d* t_cam_world);

// Jacobian of the pixel (u, v) = pi(K X_cam) of the camera-frame point X_cam with respect to the
// left-multiplicative update X_cam' = exp(w) X_cam + v of the pose T_cam_world, columns (w, v):
// the update both eq. (1) refinements (this file's and core/pose_estimation.h's) apply.
inline Eigen::Matrix<double, 2, 6> reprojection_jacobian(double fx, double fy,
                                                         const Eigen::Vector3d& X_cam) {
  const double iz = 1.0 / X_cam.z();
  Eigen::Matrix<double, 2, 3> Jp;
  Jp << fx * iz, 0, -fx * X_cam.x() * iz * iz, 0, fy * iz, -fy * X_cam.y() * iz * iz;
  Eigen::Matrix<double, 2, 6> J;
  J.leftCols<3>() = -Jp * skew(X_cam);  // rotation (left perturbation)
  J.rightCols<3>() = Jp;                // translation
  return J;
}

// Covariance of a pose refined by eq. (1), accumulated over its inliers at the final pose:
//   H = sum_i J_i^T J_i / s_i^2       (J_i = reprojection_jacobian, s_i the observation's noise
//                                      model in pixels: 1 px x the feature's pyramid scale, the
//                                      weights of the refinement's last, non-robust round)
//   sigma0^2 = chi^2 / (2n - 6),      chi^2 = sum_i |r_i|^2 / s_i^2 (a-posteriori variance
//                                      factor: the model's 1 px is scaled to the noise the
//                                      residuals show, e.g. ORB's unrefined keypoints or map error)
//                                      With an inlier gate (|r_i|^2 / s_i^2 <= gate_chi2, the
//                                      refinement's), the gate cut the largest residuals off, so
//                                      sigma0^2 is the variance factor whose gated chi-square
//                                      (2 DoF) has the inliers' mean. Monte-Carlo trace of the
//                                      covariance / empirical (tests/unit/test_pose_covariance):
//                                      noise 0.6x the model 0.96, 1x 0.89 (0.73 ungated), 1.4x
//                                      0.83: the gate also drops the worst 5-20% of the points.
//   Sigma_(w,v) = sigma0^2 H^-1       (in the refinement's left update of T_cam_world, camera
//                                      frame: rotation w, then translation v)
// covariance() converts it to what rdslam.pose_t publishes: the error [dc, dtheta] of the camera
// centre c in world (map units) and of R_world_cam as a rotation vector in the world frame
// (R_true = exp(dtheta) R, radians). From T_cam_world' = (exp(w), v) T_cam_world:
// dc = -R_cam_world^T v, dtheta = -R_cam_world^T w (first order). Map points are held fixed,
// so the map's own uncertainty is not included.
class PoseInformation {
 public:
  // `gate_chi2`: the inlier gate the points were selected by (0: none).
  explicit PoseInformation(double gate_chi2 = 0.0) : gate_chi2_(gate_chi2) {}
  // One inlier: world point, observed ideal pixel and its noise model s (pixels), at the pose.
  void add(const PinholeIntrinsics& K, const Pose& T_cam_world, const Eigen::Vector3d& p_world,
           const Eigen::Vector2d& pixel, double sigma_px);
  int count() const { return n_; }
  double chi2() const { return chi2_; }
  // sigma0^2 (see above); negative when it cannot be told (fewer than 4 points, or gated
  // residuals spread as if the noise were far larger than the gate).
  double variance_factor() const;
  // Row-major 6x6 [dc, dtheta] covariance (see above) into *out; false (out untouched) without
  // a variance factor or with a singular information matrix.
  bool covariance(const Pose& T_cam_world, std::array<double, 36>* out) const;

 private:
  Eigen::Matrix<double, 6, 6> H_ = Eigen::Matrix<double, 6, 6>::Zero();
  double chi2_ = 0.0;
  int n_ = 0;
  double gate_chi2_ = 0.0;
};

// Rotation-only pose (issue 23 item 3, pure camera rotation; core/tracker.h "Rotation-only
// tracking"). With the camera centre c held fixed, a map point p and a point at infinity (a
// unit bearing b in the world frame, kept by a rotation-only keyframe) are the same kind of
// constraint: a world direction d (p - c, or b) seen at the ideal pixel x = pi(K R d). Only
// R_cam_world is estimated; a point at infinity has no depth, so it never constrains (or
// needs) a translation or a scale.
//
// Kabsch: the rotation R minimising sum_i |a_i - R b_i|^2 (a_i in the camera frame, b_i in the
// world frame, both unit vectors; n >= 2 of them not parallel).
Eigen::Matrix3d kabsch_rotation(const Eigen::Vector3d* a_cam, const Eigen::Vector3d* b_world,
                                int n);

// Eq. (1) over the rotation only: Gauss-Newton on SO(3) (left update R' = exp(w) R) of the
// residuals (pi(K R d_i) - x_i) / sigma_i with a Huber weight (at sqrt(gate_chi2)). `rounds`
// rounds, each up to `iterations` steps, then re-classifying inlier[i] by |r_i|^2 <=
// gate_chi2. The first round uses every direction (or, with keep_initial_inliers, those whose
// inlier[i] is already 1: a consensus). Returns the inlier count at the final R (0 and R
// unusable when fewer than 2 directions are left). Does not allocate.
int refine_rotation(const PinholeIntrinsics& K, const Eigen::Vector3d* d_world,
                    const Eigen::Vector2d* x, const float* sigma, int n, Eigen::Matrix3d& R,
                    uint8_t* inlier, double gate_chi2, int rounds = 3, int iterations = 8,
                    bool keep_initial_inliers = false);

// Robust rotation from direction/pixel pairs: hypotheses from the prediction R and from
// Kabsch on `hypotheses` deterministic (seeded) 2-point samples, scored by the count within
// gate_chi2; the best is refined by refine_rotation. Returns the inlier count (R and inlier[]
// set), or 0 with R unchanged when n < 2. Does not allocate.
int estimate_rotation(const PinholeIntrinsics& K, const Eigen::Vector3d* d_world,
                      const Eigen::Vector2d* x, const float* sigma, int n, Eigen::Matrix3d& R,
                      uint8_t* inlier, double gate_chi2, int hypotheses, uint32_t seed);

// Rodrigues' formula: rotation matrix of the rotation vector w (radians).
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w);

}  // namespace rdslam
