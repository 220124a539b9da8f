#include "core/bundle_adjustment.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <unordered_map>

namespace rdslam {

namespace {

// Reprojection of a world point into a keyframe with pose [angle-axis(3), t(3)] (T_cam_world),
// residual in units of the feature's noise scale (Ceres example style: functor + Create()).
struct ReprojectionCost {
  ReprojectionCost(const PinholeIntrinsics& K, double u, double v, double inv_sigma)
      : K_(K), u_(u), v_(v), inv_sigma_(inv_sigma) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    T p[3];
    ceres::AngleAxisRotatePoint(pose, point, p);
    p[0] += pose[3];
    p[1] += pose[4];
    p[2] += pose[5];
    if (p[2] <= T(1e-6)) {
      residual[0] = T(0);
      residual[1] = T(0);
      return true;  // behind the camera: no information; classified as outlier afterwards
    }
    const T u = T(K_.fx) * p[0] / p[2] + T(K_.cx);
    const T v = T(K_.fy) * p[1] / p[2] + T(K_.cy);
    residual[0] = (u - T(u_)) * T(inv_sigma_);
    residual[1] = (v - T(v_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const PinholeIntrinsics& K, double u, double v,
                                     double inv_sigma) {
    return new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 6, 3>(
        new ReprojectionCost(K, u, v, inv_sigma));
  }

  PinholeIntrinsics K_;
  double u_, v_, inv_sigma_;
};

// Ends the solve when the caller's stop predicate says so (bundle_adjust's `stop`).
class StopCallback : public ceres::IterationCallback {
 public:
  explicit StopCallback(const std::function<bool()>& stop) : stop_(stop) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    if (!stop_()) return ceres::SOLVER_CONTINUE;
    stopped = true;
    return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
  }
  bool stopped = false;

 private:
  const std::function<bool()>& stop_;
};

void pose_to_params(const Pose& T, double* x) {
  Eigen::AngleAxisd aa(T.R);
  const Eigen::Vector3d w = aa.angle() * aa.axis();
  x[0] = w.x();
  x[1] = w.y();
  x[2] = w.z();
  x[3] = T.t.x();
  x[4] = T.t.y();
  x[5] = T.t.z();
}

Pose params_to_pose(const double* x) {
  Pose T;
  T.R = exp_so3(Eigen::Vector3d(x[0], x[1], x[2]));
  T.t = Eigen::Vector3d(x[3], x[4], x[5]);
  return T;
}

}  // namespace

void BundleAdjustmentParams::visit(ParamVisitor& v) {
  v.field("window", window, 1, 100, "local BA: covisible keyframes optimised with the new one");
  v.field("max_fixed", max_fixed, 1, 200, "local BA: fixed anchor keyframes outside the window");
  v.field("iterations", iterations, 1, 100, "Levenberg-Marquardt iterations per pass");
  v.field("huber_px", huber_px, 0.1, 100.0, "Huber threshold on the normalised residual");
  v.field("second_pass", second_pass, "re-optimise after removing outliers");
  v.field("keep_scale", keep_scale,
          "with a single fixed keyframe (a young map), rescale the solution about it so that the "
          "optimised keyframes keep their scale (the cost is invariant to it)");
}

BundleAdjustmentStats bundle_adjust(Map& map, const PinholeIntrinsics& K,
                                    const std::vector<int>& window_kfs,
                                    const BundleAdjustmentParams& params,
                                    const std::function<bool()>& stop) {
  BundleAdjustmentStats st;
  std::set<int> window(window_kfs.begin(), window_kfs.end());
  std::set<int64_t> pts;
  for (int id : window) {
    const Keyframe* kf = map.keyframe(id);
    if (!kf) continue;
    for (int64_t pid : kf->point_of) {
      if (pid >= 0 && map.point(pid)) pts.insert(pid);
    }
  }
  // Fixed anchors: keyframes outside the window that see the points, most shared first.
  std::unordered_map<int, int> shared;
  for (int64_t pid : pts) {
    for (const auto& o : map.point(pid)->obs) {
      if (!window.count(o.kf)) ++shared[o.kf];
    }
  }
  std::vector<std::pair<int, int>> anchors;
  for (const auto& [id, c] : shared) anchors.emplace_back(c, id);
  std::sort(anchors.begin(), anchors.end(), std::greater<>());
  std::set<int> fixed;
  for (size_t i = 0; i < anchors.size() && static_cast<int>(i) < params.max_fixed; ++i) {
    fixed.insert(anchors[i].second);
  }
  // A pose block held constant: an anchor, or a keyframe the map fixes (the first ones).
  const auto is_fixed = [&](int id) {
    const Keyframe* kf = map.keyframe(id);
    return fixed.count(id) || (kf && kf->fixed);
  };
  std::unordered_map<int, std::array<double, 6>> pose_x;
  for (int id : window) {
    if (map.keyframe(id)) pose_to_params(map.keyframe(id)->T_cam_world, pose_x[id].data());
  }
  for (int id : fixed) pose_to_params(map.keyframe(id)->T_cam_world, pose_x[id].data());
  std::unordered_map<int64_t, std::array<double, 3>> point_x;
  for (int64_t pid : pts) {
    const Eigen::Vector3d& p = map.point(pid)->p_world;
    point_x[pid] = {p.x(), p.y(), p.z()};
  }

  struct Res {
    int64_t pid;
    int kf;
    int feat;
  };
  for (int pass = 0; pass < (params.second_pass ? 2 : 1) && !st.stopped; ++pass) {
    ceres::Problem::Options popt;
    popt.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(popt);
    ceres::HuberLoss loss(params.huber_px);
    std::vector<Res> residuals;
    for (int64_t pid : pts) {
      MapPoint* p = map.point(pid);
      if (!p) continue;
      for (const auto& o : p->obs) {
        auto it = pose_x.find(o.kf);
        if (it == pose_x.end()) continue;
        const Keyframe* kf = map.keyframe(o.kf);
        const cv::Point2f& x = kf->features.un[o.feat];
        const double inv_sigma = 1.0 / kf->features.scale[o.feat];
        problem.AddResidualBlock(ReprojectionCost::Create(K, x.x, x.y, inv_sigma), &loss,
                                 it->second.data(), point_x[pid].data());
        residuals.push_back({pid, o.kf, o.feat});
      }
    }
    if (residuals.empty()) return st;
    int nfixed = 0;
    for (auto& [id, x] : pose_x) {
      if (!problem.HasParameterBlock(x.data())) continue;
      if (is_fixed(id)) {
        problem.SetParameterBlockConstant(x.data());
        ++nfixed;
      }
    }
    ceres::Solver::Options opt;
    opt.linear_solver_type = ceres::SPARSE_SCHUR;
    opt.max_num_iterations = pass == 0 ? params.iterations : params.iterations / 2 + 1;
    opt.num_threads = 1;
    opt.logging_type = ceres::SILENT;
    StopCallback stop_cb(stop);
    if (stop) opt.callbacks.push_back(&stop_cb);
    ceres::Solver::Summary summary;
    ceres::Solve(opt, &problem, &summary);
    st.stopped = stop_cb.stopped;
    if (pass == 0) st.initial_cost = summary.initial_cost;
    st.final_cost = summary.final_cost;
    st.residuals = static_cast<int>(residuals.size());
    st.fixed = nfixed;
    // Remove observations that stay inconsistent (chi-square 2 DoF, 95%) or behind a camera.
    for (const Res& r : residuals) {
      const Pose T = params_to_pose(pose_x[r.kf].data());
      const auto& px = point_x[r.pid];
      const Eigen::Vector3d pc = T * Eigen::Vector3d(px[0], px[1], px[2]);
      const Keyframe* kf = map.keyframe(r.kf);
      const cv::Point2f& x = kf->features.un[r.feat];
      const double s = kf->features.scale[r.feat];
      bool bad = pc.z() <= 1e-6;
      if (!bad) {
        const Eigen::Vector2d e = K.project(pc) - Eigen::Vector2d(x.x, x.y);
        bad = e.squaredNorm() / (s * s) > 5.991;
      }
      if (bad) {
        map.remove_observation(r.pid, r.kf);
        ++st.outliers_removed;
      }
    }
  }
  // Gauge: with one fixed keyframe the cost is invariant to a scaling about its centre, so
  // the scale of the solution is arbitrary (Levenberg-Marquardt's damping leaks into it).
  // Scale it back to the keyframes' scale before the optimisation (least squares).
  if (params.keep_scale && st.fixed == 1) {
    const Keyframe* gauge = nullptr;
    int gauges = 0;
    for (auto& [id, x] : pose_x) {
      const Keyframe* kf = map.keyframe(id);
      if (kf && is_fixed(id)) {
        gauge = kf;
        ++gauges;
      }
    }
    if (gauges == 1) {
      const Eigen::Vector3d c0 = gauge->T_cam_world.centre();
      double num = 0, den = 0;
      for (auto& [id, x] : pose_x) {
        const Keyframe* kf = map.keyframe(id);
        if (!kf || kf == gauge) continue;
        const Eigen::Vector3d before = kf->T_cam_world.centre() - c0;
        const Eigen::Vector3d after = params_to_pose(x.data()).centre() - c0;
        num += before.dot(after);
        den += after.squaredNorm();
      }
      const double s = den > 0 ? num / den : 1.0;
      if (std::isfinite(s) && s > 0.5 && s < 2.0) {
        st.rescale = s;
        for (auto& [id, x] : pose_x) {
          const Keyframe* kf = map.keyframe(id);
          if (!kf || kf == gauge) continue;
          Pose T = params_to_pose(x.data());
          const Eigen::Vector3d c = T.centre();
          T.t = -(T.R * (c0 + s * (c - c0)));
          pose_to_params(T, x.data());
        }
        for (auto& [pid, x] : point_x) {
          const Eigen::Vector3d p = c0 + s * (Eigen::Vector3d(x[0], x[1], x[2]) - c0);
          x = {p.x(), p.y(), p.z()};
        }
      }
    }
  }
  // Write back.
  for (auto& [id, x] : pose_x) {
    Keyframe* kf = map.keyframe(id);
    if (!kf || fixed.count(id) || kf->fixed) continue;
    kf->T_cam_world = params_to_pose(x.data());
  }
  for (auto& [pid, x] : point_x) {
    MapPoint* p = map.point(pid);
    if (!p) continue;
    if (p->obs.size() < 2) {
      map.erase_point(pid);
      continue;
    }
    p->p_world = Eigen::Vector3d(x[0], x[1], x[2]);
  }
  st.keyframes = static_cast<int>(window.size());
  st.points = static_cast<int>(pts.size());
  return st;
}

}  // namespace rdslam
