#include "core/pose_refine.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <cmath>

namespace rdslam {

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w) {
  const double th2 = w.squaredNorm();
  Eigen::Matrix3d W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  if (th2 < 1e-16) return Eigen::Matrix3d::Identity() + W;
  const double th = std::sqrt(th2);
  return Eigen::Matrix3d::Identity() + (std::sin(th) / th) * W +
         ((1.0 - std::cos(th)) / th2) * (W * W);
}

namespace {

// Sum of squared pixel errors and, when H/g are given, the Gauss-Newton system for the
// left-multiplicative update X_cam' = exp(w) X_cam + v of the camera-frame points.
double accumulate(const Eigen::Vector2d* px, const Eigen::Vector3d* pw, const uint8_t* mask,
                  int count, const Intrinsics& K, const Eigen::Matrix3d& R,
                  const Eigen::Vector3d& t, Eigen::Matrix<double, 6, 6>* H,
                  Eigen::Matrix<double, 6, 1>* g, int* used) {
  double cost = 0.0;
  int n = 0;
  if (H) {
    H->setZero();
    g->setZero();
  }
  for (int i = 0; i < count; ++i) {
    if (mask && !mask[i]) continue;
    const Eigen::Vector3d Xc = R * pw[i] + t;
    if (!(Xc.z() > 1e-9) || !std::isfinite(Xc.x() + Xc.y() + px[i].x() + px[i].y())) continue;
    const double iz = 1.0 / Xc.z();
    const double u = K.fx * Xc.x() * iz + K.cx;
    const double v = K.fy * Xc.y() * iz + K.cy;
    const double eu = u - px[i].x(), ev = v - px[i].y();
    cost += eu * eu + ev * ev;
    ++n;
    if (!H) continue;
    // d(u,v)/dXc, then dXc/d(w, v) = [-[Xc]x | I].
    Eigen::Matrix<double, 2, 3> Jp;
    Jp << K.fx * iz, 0, -K.fx * Xc.x() * iz * iz, 0, K.fy * iz, -K.fy * Xc.y() * iz * iz;
    Eigen::Matrix3d Xx;
    Xx << 0, -Xc.z(), Xc.y(), Xc.z(), 0, -Xc.x(), -Xc.y(), Xc.x(), 0;
    Eigen::Matrix<double, 2, 6> J;
    J.leftCols<3>() = -Jp * Xx;
    J.rightCols<3>() = Jp;
    H->noalias() += J.transpose() * J;
    g->noalias() += J.transpose() * Eigen::Vector2d(eu, ev);
  }
  if (used) *used = n;
  return cost;
}

}  // namespace

RefineResult refine_pose(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world,
                         const uint8_t* mask, int count, const Intrinsics& K, int max_iterations,
                         Eigen::Matrix3d* R_cam_world, Eigen::Vector3d* t_cam_world) {
  RefineResult res;
  Eigen::Matrix3d R = *R_cam_world;
  Eigen::Vector3d t = *t_cam_world;
  Eigen::Matrix<double, 6, 6> H;
  Eigen::Matrix<double, 6, 1> g;
  double cost = accumulate(pixels, p_world, mask, count, K, R, t, &H, &g, &res.used_points);
  res.initial_cost = res.final_cost = cost;
  if (res.used_points < 3) return res;
  double lambda = 1e-4;  // Levenberg-Marquardt damping, relative to diag(H)
  for (int it = 0; it < max_iterations; ++it) {
    res.iterations = it + 1;
    Eigen::Matrix<double, 6, 6> A = H;
    for (int k = 0; k < 6; ++k) A(k, k) += lambda * (H(k, k) + 1e-9);
    const Eigen::Matrix<double, 6, 1> delta = A.ldlt().solve(-g);
    if (!delta.allFinite()) break;
    const Eigen::Matrix3d dR = so3_exp(delta.head<3>());
    const Eigen::Matrix3d R_new = dR * R;
    const Eigen::Vector3d t_new = dR * t + delta.tail<3>();
    int used_new = 0;
    const double cost_new =
        accumulate(pixels, p_world, mask, count, K, R_new, t_new, nullptr, nullptr, &used_new);
    // Accept only steps that lower the cost without dropping points behind the camera.
    if (cost_new < cost && used_new >= res.used_points) {
      R = R_new;
      t = t_new;
      const double rel = (cost - cost_new) / (cost + 1e-30);
      cost = accumulate(pixels, p_world, mask, count, K, R, t, &H, &g, &res.used_points);
      lambda = std::max(lambda * 0.1, 1e-9);
      if (delta.squaredNorm() < 1e-20 || rel < 1e-10) {
        res.converged = true;
        break;
      }
    } else {
      lambda *= 10.0;
      if (lambda > 1e8) {
        res.converged = true;  // no descent direction left: at a minimum up to round-off
        break;
      }
    }
  }
  // Re-orthonormalise against drift from repeated products.
  R = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  *R_cam_world = R;
  *t_cam_world = t;
  res.final_cost = accumulate(pixels, p_world, mask, count, K, R, t, nullptr, nullptr, nullptr);
  return res;
}

}  // namespace rdslam
