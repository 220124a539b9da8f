// Pose solvers over 2D-3D correspondences, the building blocks of the robust estimators in
// core/parsac.h (RDSLAM, Tan et al. ISMAR 2013, Sec. 5):
//  - the paper's model: the 3x4 projective matrix from >= 6 points by the (normalised) DLT,
//    decomposed into K[R|T] with the known intrinsics K;
//  - beyond the paper: the calibrated minimal solver P3P (Grunert 1841, in the form reviewed by
//    Haralick et al., IJCV 1994), whose sample needs 3 (+1 to disambiguate) points instead of 6;
//  - OpenCV's solvePnPRansac with MAGSAC++ scoring, an outside reference for the benchmark.
//
// Ownership: free functions over caller-owned arrays. Threads: any; no shared state. None of
// them allocates on the heap except opencv_magsac_pnp() (a reference, not for the tracker).
#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace rdslam {

using Mat34 = Eigen::Matrix<double, 3, 4>;

// Pinhole intrinsics of ideal (undistorted) pixels.
struct Intrinsics {
  double fx = 525.0;
  double fy = 525.0;
  double cx = 319.5;
  double cy = 239.5;
};

// x ~ P * [X; 1] for the correspondences `idx[0..count)` (all points 0..count when idx is
// null): the least-squares DLT null vector of the 2count x 12 system built on normalised
// camera coordinates (K^-1 x) and on world points mapped by (X - centre) / scale, which keeps
// the 12x12 normal matrix well conditioned (Hartley's normalisation). Returns the matrix in
// pixels and world units with its sign chosen so that det(P[:, :3]) > 0 (points in front have
// positive w). count >= 6. Returns false for degenerate input (non-finite or rank-deficient).
bool solve_dlt(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world, const int* idx,
               int count, const Intrinsics& K, const Eigen::Vector3d& centre, double scale,
               Mat34* P);

// P = K [R | T] up to a positive scale (Sec. 5, "we decompose the estimated projective matrix
// to R and T"): R is the rotation nearest (Frobenius) to K^-1 P[:, :3] / s, s the geometric mean of
// its singular values, T = K^-1 P[:, 3] / s. Returns false when P[:, :3] is singular or not finite.
bool decompose_projection(const Mat34& P, const Intrinsics& K, Eigen::Matrix3d* R_cam_world,
                          Eigen::Vector3d* t_cam_world);

// K [R | t] as a projective matrix.
Mat34 compose_projection(const Intrinsics& K, const Eigen::Matrix3d& R_cam_world,
                         const Eigen::Vector3d& t_cam_world);

// Real roots of c[0] x^4 + c[1] x^3 + c[2] x^2 + c[3] x + c[4] (Ferrari's method with Newton
// polishing); c[0] != 0. Returns the number of roots written to `roots` (<= 4).
int solve_quartic(const double c[5], double roots[4]);

// P3P: unit bearing vectors f[i] (camera frame) of world points X[i]; writes up to 4 poses
// (R_cam_world, t_cam_world) with X_cam = R X + t. Returns the number of solutions.
int solve_p3p(const Eigen::Vector3d f[3], const Eigen::Vector3d X[3], Eigen::Matrix3d R[4],
              Eigen::Vector3d t[4]);

// OpenCV's solvePnPRansac with USAC MAGSAC++ scoring (outside reference, Barath et al. CVPR
// 2020): `max_iterations`, reprojection `threshold_px`, `confidence`, `seed`. Allocates.
// Returns false when OpenCV finds no model; fills R, t and inlier_mask (n bytes, 0/1).
bool opencv_magsac_pnp(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world, int count,
                       const Intrinsics& K, int max_iterations, double threshold_px,
                       double confidence, int seed, Eigen::Matrix3d* R_cam_world,
                       Eigen::Vector3d* t_cam_world, uint8_t* inlier_mask);

}  // namespace rdslam
