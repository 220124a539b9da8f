// Camera pose refinement by minimising the reprojection error of eq. (1) of RDSLAM (Tan et al.,
// ISMAR 2013): min_{R,T} sum_i || x_i - pi(K (R X_i + T)) ||^2 over the inliers.
//
// A fixed-size Levenberg-Marquardt in Eigen (6x6 normal equations, left-multiplicative
// update on SE(3)): no heap allocation, so the tracker can call it every frame; Ceres stays in
// the mapper's bundle adjustment.
//
// Ownership: free function over caller-owned arrays. Threads: any; no shared state.
#pragma once

#include <Eigen/Core>
#include <cstdint>

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

// Rodrigues' formula: rotation matrix of the rotation vector w (radians).
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w);

}  // namespace rdslam
