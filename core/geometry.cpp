#include "core/geometry.h"

#include <Eigen/SVD>
#include <cmath>

namespace rdslam {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double th = w.norm();
  if (th < 1e-10) return Eigen::Matrix3d::Identity() + skew(w);
  return Eigen::AngleAxisd(th, w / th).toRotationMatrix();
}

bool triangulate_dlt(const Pose& T0, const Eigen::Vector3d& b0, const Pose& T1,
                     const Eigen::Vector3d& b1, Eigen::Vector3d& p_world) {
  Eigen::Matrix<double, 3, 4> P0, P1;
  P0.leftCols<3>() = T0.R;
  P0.col(3) = T0.t;
  P1.leftCols<3>() = T1.R;
  P1.col(3) = T1.t;
  Eigen::Matrix4d A;
  A.row(0) = b0.x() * P0.row(2) - P0.row(0);
  A.row(1) = b0.y() * P0.row(2) - P0.row(1);
  A.row(2) = b1.x() * P1.row(2) - P1.row(0);
  A.row(3) = b1.y() * P1.row(2) - P1.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X(3)) < 1e-12) return false;
  p_world = X.head<3>() / X(3);
  return p_world.allFinite();
}

double parallax_cos(const Eigen::Vector3d& p_world, const Eigen::Vector3d& c0,
                    const Eigen::Vector3d& c1) {
  const Eigen::Vector3d a = p_world - c0;
  const Eigen::Vector3d b = p_world - c1;
  const double na = a.norm(), nb = b.norm();
  if (na < 1e-12 || nb < 1e-12) return 1.0;
  return a.dot(b) / (na * nb);
}

double refine_point(const PinholeIntrinsics& K, const Pose* poses, const Eigen::Vector2d* obs,
                    const double* sigma_px, int n, Eigen::Vector3d& p_world, int iterations) {
  double rms = 0;
  for (int it = 0; it <= iterations; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    double sum = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d pc = poses[i] * p_world;
      if (pc.z() <= 1e-9) return -1.0;
      const double iz = 1.0 / pc.z();
      const double w = 1.0 / (sigma_px[i] * sigma_px[i]);
      const Eigen::Vector2d e = K.project(pc) - obs[i];
      sum += w * e.squaredNorm();
      Eigen::Matrix<double, 2, 3> Jp;
      Jp << K.fx * iz, 0, -K.fx * pc.x() * iz * iz, 0, K.fy * iz, -K.fy * pc.y() * iz * iz;
      const Eigen::Matrix<double, 2, 3> J = Jp * poses[i].R;
      H += w * J.transpose() * J;
      g += w * J.transpose() * e;
    }
    rms = std::sqrt(sum / std::max(1, n));
    if (it == iterations) break;
    const Eigen::Vector3d dx = H.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    p_world += dx;
    if (dx.norm() < 1e-9 * (1.0 + p_world.norm())) break;
  }
  return rms;
}

Eigen::Matrix3d fundamental_from_poses(const PinholeIntrinsics& K, const Pose& T0, const Pose& T1) {
  // T_1_0 = T1 * T0^-1; E = [t]x R; F = K^-T E K^-1.
  const Pose T10 = T1 * T0.inverse();
  const Eigen::Matrix3d E = skew(T10.t) * T10.R;
  Eigen::Matrix3d Kinv;
  Kinv << 1.0 / K.fx, 0, -K.cx / K.fx, 0, 1.0 / K.fy, -K.cy / K.fy, 0, 0, 1;
  return Kinv.transpose() * E * Kinv;
}

}  // namespace rdslam
