#include "core/pose_refine.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
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
    const Eigen::Matrix<double, 2, 6> J = reprojection_jacobian(K.fx, K.fy, Xc);
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

void PoseInformation::add(const PinholeIntrinsics& K, const Pose& T_cam_world,
                          const Eigen::Vector3d& p_world, const Eigen::Vector2d& pixel,
                          double sigma_px) {
  const Eigen::Vector3d Xc = T_cam_world * p_world;
  if (!(Xc.z() > 1e-6) || !(sigma_px > 0.0)) return;
  const double w = 1.0 / (sigma_px * sigma_px);
  const Eigen::Matrix<double, 2, 6> J = reprojection_jacobian(K.fx, K.fy, Xc);
  H_.noalias() += w * J.transpose() * J;
  chi2_ += w * (K.project(Xc) - pixel).squaredNorm();
  ++n_;
}

namespace {

// Mean of a chi-square (2 DoF) variable scaled by s2 and gated at `gate`:
// s2 * E[X | X <= gate / s2], E[X | X <= x] = 2 - x e^(-x/2) / (1 - e^(-x/2)).
double gated_chi2_mean(double s2, double gate) {
  const double x = gate / s2;
  const double e = std::exp(-0.5 * x);
  return s2 * (2.0 - x * e / (1.0 - e));
}

}  // namespace

double PoseInformation::variance_factor() const {
  if (n_ < 4) return -1.0;  // 2n - 6 > 0 residual degrees of freedom
  const double s2 = chi2_ / (2.0 * n_ - 6.0);
  if (gate_chi2_ <= 0.0 || s2 <= 0.0) return s2;
  // Solve gated_chi2_mean(s2g) = 2 s2 (the inliers' mean chi-square, dof-corrected); the left
  // side increases with s2g towards gate / 2, and is at most 2 s2g, so s2g >= s2.
  const double m = 2.0 * s2;
  double lo = s2, hi = s2;
  for (int k = 0; gated_chi2_mean(hi, gate_chi2_) < m; ++k) {
    if (k == 40) return -1.0;  // no such noise: the residuals fill the gate
    lo = hi;
    hi *= 2.0;
  }
  for (int k = 0; k < 50; ++k) {
    const double mid = 0.5 * (lo + hi);
    (gated_chi2_mean(mid, gate_chi2_) < m ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

bool PoseInformation::covariance(const Pose& T_cam_world, std::array<double, 36>* out) const {
  const double sigma0_sq = variance_factor();
  if (sigma0_sq < 0.0) return false;
  const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(H_);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, 6, 6> H_inv = llt.solve(Eigen::Matrix<double, 6, 6>::Identity());
  // (w, v) -> (dc, dtheta): dc = -R^T v, dtheta = -R^T w.
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  A.topRightCorner<3, 3>() = -T_cam_world.R.transpose();
  A.bottomLeftCorner<3, 3>() = -T_cam_world.R.transpose();
  Eigen::Matrix<double, 6, 6> S = sigma0_sq * (A * H_inv * A.transpose());
  S = 0.5 * (S + S.transpose()).eval();
  if (!S.allFinite()) return false;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) (*out)[static_cast<size_t>(6 * r + c)] = S(r, c);
  }
  return true;
}

namespace {

// Squared normalised residual of direction d at rotation R (-1: behind the camera).
double rotation_residual(const PinholeIntrinsics& K, const Eigen::Matrix3d& R,
                         const Eigen::Vector3d& d, const Eigen::Vector2d& x, float sigma,
                         Eigen::Vector2d* r = nullptr, Eigen::Vector3d* X = nullptr) {
  const Eigen::Vector3d Xc = R * d;
  if (!(Xc.z() > 1e-9 * d.norm())) return -1.0;
  const Eigen::Vector2d e = (K.project(Xc) - x) / double(sigma);
  if (r) *r = e;
  if (X) *X = Xc;
  return e.squaredNorm();
}

int count_rotation_inliers(const PinholeIntrinsics& K, const Eigen::Vector3d* d,
                           const Eigen::Vector2d* x, const float* sigma, int n,
                           const Eigen::Matrix3d& R, double gate_chi2, uint8_t* inlier) {
  int c = 0;
  for (int i = 0; i < n; ++i) {
    const double e2 = rotation_residual(K, R, d[i], x[i], sigma[i]);
    const bool in = e2 >= 0.0 && e2 <= gate_chi2;
    if (inlier) inlier[i] = in;
    c += in;
  }
  return c;
}

}  // namespace

Eigen::Matrix3d kabsch_rotation(const Eigen::Vector3d* a_cam, const Eigen::Vector3d* b_world,
                                int n) {
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();  // sum a b^T
  for (int i = 0; i < n; ++i) M.noalias() += a_cam[i] * b_world[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) S(2, 2) = -1.0;
  return svd.matrixU() * S * svd.matrixV().transpose();
}

int refine_rotation(const PinholeIntrinsics& K, const Eigen::Vector3d* d_world,
                    const Eigen::Vector2d* x, const float* sigma, int n, Eigen::Matrix3d& R,
                    uint8_t* inlier, double gate_chi2, int rounds, int iterations,
                    bool keep_initial_inliers) {
  const double huber = std::sqrt(gate_chi2);
  if (!keep_initial_inliers) std::fill(inlier, inlier + n, uint8_t{1});
  for (int round = 0; round < rounds; ++round) {
    for (int it = 0; it < iterations; ++it) {
      Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      int used = 0;
      for (int i = 0; i < n; ++i) {
        if (!inlier[i]) continue;
        Eigen::Vector2d r;
        Eigen::Vector3d Xc;
        const double e2 = rotation_residual(K, R, d_world[i], x[i], sigma[i], &r, &Xc);
        if (e2 < 0.0) continue;
        const double e = std::sqrt(e2);
        const double w = e <= huber ? 1.0 : huber / e;
        const Eigen::Matrix<double, 2, 3> J =
            reprojection_jacobian(K.fx, K.fy, Xc).leftCols<3>() / double(sigma[i]);
        H.noalias() += w * J.transpose() * J;
        g.noalias() += w * J.transpose() * r;
        ++used;
      }
      if (used < 2) return 0;
      const Eigen::Vector3d dw = H.ldlt().solve(-g);
      if (!dw.allFinite()) return 0;
      R = so3_exp(dw) * R;
      if (dw.norm() < 1e-9) break;
    }
    const int c = count_rotation_inliers(K, d_world, x, sigma, n, R, gate_chi2, inlier);
    if (c < 2) return c;
  }
  return count_rotation_inliers(K, d_world, x, sigma, n, R, gate_chi2, inlier);
}

int estimate_rotation(const PinholeIntrinsics& K, const Eigen::Vector3d* d_world,
                      const Eigen::Vector2d* x, const float* sigma, int n, Eigen::Matrix3d& R,
                      uint8_t* inlier, double gate_chi2, int hypotheses, uint32_t seed) {
  if (n < 2) return 0;
  Eigen::Matrix3d best = R;
  int best_count = count_rotation_inliers(K, d_world, x, sigma, n, R, gate_chi2, nullptr);
  uint32_t s = seed * 2654435761u + 1u;
  auto next = [&s](int m) {  // xorshift32: deterministic, no allocation
    s ^= s << 13;
    s ^= s >> 17;
    s ^= s << 5;
    return static_cast<int>(s % static_cast<uint32_t>(m));
  };
  for (int h = 0; h < hypotheses; ++h) {
    const int i = next(n);
    const int j = next(n);
    if (i == j) continue;
    Eigen::Vector3d a[2], b[2];
    const int ij[2] = {i, j};
    for (int k = 0; k < 2; ++k) {
      a[k] = K.unproject(x[ij[k]].x(), x[ij[k]].y()).normalized();
      b[k] = d_world[ij[k]].normalized();
    }
    if (a[0].cross(a[1]).norm() < 1e-3 || b[0].cross(b[1]).norm() < 1e-3) continue;
    const Eigen::Matrix3d Rh = kabsch_rotation(a, b, 2);
    const int c = count_rotation_inliers(K, d_world, x, sigma, n, Rh, gate_chi2, nullptr);
    if (c > best_count) {
      best_count = c;
      best = Rh;
    }
  }
  if (best_count < 2) return 0;
  R = best;
  // Refined from the consensus.
  count_rotation_inliers(K, d_world, x, sigma, n, R, gate_chi2, inlier);
  Eigen::Matrix3d Rr = R;
  const int c = refine_rotation(K, d_world, x, sigma, n, Rr, inlier, gate_chi2, 3, 8, true);
  if (c >= best_count) R = Rr;
  return count_rotation_inliers(K, d_world, x, sigma, n, R, gate_chi2, inlier);
}

}  // namespace rdslam
