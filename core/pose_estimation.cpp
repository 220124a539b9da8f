#include "core/pose_estimation.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "core/pose_refine.h"

namespace rdslam {

PoseRefineStats refine_pose(const PinholeIntrinsics& K, const Eigen::Vector3d* p_world,
                            const Eigen::Vector2d* obs, const float* sigma_px, int n, Pose& T,
                            uint8_t* inlier, int rounds, int iterations,
                            bool keep_initial_inliers) {
  PoseRefineStats st;
  if (n <= 0) return st;
  if (!keep_initial_inliers) {
    for (int i = 0; i < n; ++i) inlier[i] = 1;
  }
  const double huber = std::sqrt(kInlierChi2);
  for (int round = 0; round < rounds; ++round) {
    const bool robust = round < rounds - 1;
    for (int it = 0; it < iterations; ++it) {
      Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
      Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
      int used = 0;
      for (int i = 0; i < n; ++i) {
        if (!inlier[i]) continue;
        const Eigen::Vector3d pc = T * p_world[i];
        if (pc.z() <= 1e-6) continue;
        const Eigen::Vector2d e = K.project(pc) - obs[i];
        const double inv_s = 1.0 / sigma_px[i];
        const double chi = e.squaredNorm() * inv_s * inv_s;
        double w = inv_s * inv_s;
        if (robust && chi > kInlierChi2) w *= huber / std::sqrt(chi);
        const Eigen::Matrix<double, 2, 6> J = reprojection_jacobian(K.fx, K.fy, pc);
        H.noalias() += w * J.transpose() * J;
        g.noalias() += w * J.transpose() * e;
        ++used;
      }
      if (used < 4) break;
      const Eigen::Matrix<double, 6, 1> dx = H.ldlt().solve(-g);
      if (!dx.allFinite()) break;
      const Eigen::Matrix3d dR = exp_so3(dx.head<3>());
      T.R = dR * T.R;
      T.t = dR * T.t + dx.tail<3>();
      if (dx.squaredNorm() < 1e-12) break;
    }
    // Re-classify every correspondence, including earlier outliers (they may come back).
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d pc = T * p_world[i];
      if (pc.z() <= 1e-6) {
        inlier[i] = 0;
        continue;
      }
      const Eigen::Vector2d e = K.project(pc) - obs[i];
      const double chi = e.squaredNorm() / (double(sigma_px[i]) * sigma_px[i]);
      inlier[i] = chi <= kInlierChi2 ? 1 : 0;
    }
  }
  // Orthonormalise against drift from the repeated left updates.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(T.R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.R = svd.matrixU() * svd.matrixV().transpose();
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    if (!inlier[i]) continue;
    ++st.inliers;
    sum += (K.project(T * p_world[i]) - obs[i]).squaredNorm();
  }
  st.rms_px = st.inliers ? std::sqrt(sum / st.inliers) : 0.0;
  return st;
}

PoseEstimator::PoseEstimator(const ParsacParams& params, const CameraModel& camera,
                             int max_correspondences)
    : K_{camera.fx, camera.fy, camera.cx, camera.cy},
      max_n_(max_correspondences),
      robust_(params, camera, max_correspondences) {}

int PoseEstimator::estimate(const Eigen::Vector3d* p_world, const Eigen::Vector2d* obs,
                            const float* sigma_px, int n, Pose& T, uint8_t* inlier,
                            const Pose* guess) {
  if (n < 6) return 0;
  n = std::min(n, max_n_);
  Eigen::Isometry3d g = Eigen::Isometry3d::Identity();
  if (guess) {
    g.linear() = guess->R;
    g.translation() = guess->t;
  }
  PoseEstimate res;
  const PoseStatus st = robust_.estimate(obs, p_world, n, guess ? &g : nullptr, inlier, &res);
  if (st != PoseStatus::kOk) return 0;
  T.R = res.T_cam_world.linear();
  T.t = res.T_cam_world.translation();
  // Sec. 5: "decompose ... into R and T, and then refine them by minimizing (1)" over the
  // robust estimator's inliers. Starting eq. (1) from all correspondences instead would let
  // the rejected ones (e.g. a rigidly moving object, Figure 8) pull the pose back through
  // the robust kernel before the first re-classification.
  return refine_pose(K_, p_world, obs, sigma_px, n, T, inlier, 4, 10, true).inliers;
}

}  // namespace rdslam
