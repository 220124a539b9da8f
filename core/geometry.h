// Small multi-view geometry helpers shared by the SLAM modules: rigid poses, projection,
// two-view and multi-view triangulation, parallax.
//
// Convention (OpenVINS style names): a pose T_cam_world maps world points into the camera,
// x_cam = R * p_world + t. The camera centre in world is -R^T t.
//
// Ownership: value types and pure functions. Threads: any; no shared state.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rdslam {

struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return R * p + t; }
  Pose operator*(const Pose& o) const { return Pose{R * o.R, R * o.t + t}; }
  Pose inverse() const { return Pose{R.transpose(), -R.transpose() * t}; }
  // Camera centre in world coordinates when this is T_cam_world.
  Eigen::Vector3d centre() const { return -R.transpose() * t; }
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// Pinhole intrinsics of undistorted (ideal) pixels.
struct PinholeIntrinsics {
  double fx = 1, fy = 1, cx = 0, cy = 0;
  Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const {
    const double iz = 1.0 / p_cam.z();
    return {fx * p_cam.x() * iz + cx, fy * p_cam.y() * iz + cy};
  }
  // Unit-depth bearing (x, y, 1) of an ideal pixel.
  Eigen::Vector3d unproject(double u, double v) const {
    return {(u - cx) / fx, (v - cy) / fy, 1.0};
  }
};

// so(3) exponential (Rodrigues).
Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w);
Eigen::Matrix3d skew(const Eigen::Vector3d& v);

// Linear (DLT) triangulation of one point from two views; returns false when the system is
// degenerate. `b0`, `b1` are unit-depth bearings (x, y, 1) in each camera.
bool triangulate_dlt(const Pose& T0, const Eigen::Vector3d& b0, const Pose& T1,
                     const Eigen::Vector3d& b1, Eigen::Vector3d& p_world);

// Cosine of the angle at `p_world` between the rays to the two camera centres.
double parallax_cos(const Eigen::Vector3d& p_world, const Eigen::Vector3d& c0,
                    const Eigen::Vector3d& c1);

// Multi-view point estimate (Sec. 4, the track equation): Gauss-Newton on the reprojection
// error over all views of a track, starting from `p_world`. `scale_px` is the per-view
// measurement standard deviation in pixels. Returns the final RMS error in pixels (weighted),
// or a negative value if a point ends up behind a camera.
double refine_point(const PinholeIntrinsics& K, const Pose* poses, const Eigen::Vector2d* obs,
                    const double* sigma_px, int n, Eigen::Vector3d& p_world, int iterations = 5);

// Fundamental matrix of the pair: x1^T F x0 = 0 for ideal pixels, from T_cam0_world,
// T_cam1_world.
Eigen::Matrix3d fundamental_from_poses(const PinholeIntrinsics& K, const Pose& T0, const Pose& T1);

// Squared distance (pixels^2) of x1 to the epipolar line F x0.
inline double epipolar_dist2(const Eigen::Matrix3d& F, const Eigen::Vector2d& x0,
                             const Eigen::Vector2d& x1) {
  const Eigen::Vector3d l = F * Eigen::Vector3d(x0.x(), x0.y(), 1.0);
  const double num = l.x() * x1.x() + l.y() * x1.y() + l.z();
  const double den = l.x() * l.x() + l.y() * l.y();
  return den > 1e-12 ? num * num / den : 1e12;
}

}  // namespace rdslam
