#include "core/trajectory_eval.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace rdslam {

const char* to_string(Alignment a) {
  switch (a) {
    case Alignment::kNone:
      return "none";
    case Alignment::kSe3:
      return "se3";
    case Alignment::kSim3:
      return "sim3";
  }
  return "?";
}

bool parse_alignment(const std::string& text, Alignment& out) {
  if (text == "none") {
    out = Alignment::kNone;
  } else if (text == "se3") {
    out = Alignment::kSe3;
  } else if (text == "sim3") {
    out = Alignment::kSim3;
  } else {
    return false;
  }
  return true;
}

namespace {

// Index in `stamps` of the stamp nearest to `t` within max_diff, or -1. Ties go to the
// earlier stamp, as in evo's matching_time_indices (binary-search branch).
long nearest_sorted(const std::vector<int64_t>& stamps, int64_t t, int64_t max_diff) {
  if (stamps.empty() || t < stamps.front() - max_diff || t > stamps.back() + max_diff) return -1;
  size_t up =
      static_cast<size_t>(std::upper_bound(stamps.begin(), stamps.end(), t) - stamps.begin());
  if (up >= stamps.size()) up = stamps.size() - 1;
  const int64_t diff_ub = stamps[up] - t;
  const int64_t diff_lb = up > 0 ? t - stamps[up - 1] : std::numeric_limits<int64_t>::max();
  if (diff_ub <= max_diff && diff_ub < diff_lb) return static_cast<long>(up);
  if (diff_lb <= max_diff && diff_lb <= diff_ub) return static_cast<long>(up - 1);
  return -1;
}

// Unsorted fallback: first index of the minimal absolute difference (numpy.argmin).
long nearest_linear(const std::vector<int64_t>& stamps, int64_t t, int64_t max_diff) {
  long best = -1;
  int64_t best_diff = std::numeric_limits<int64_t>::max();
  for (size_t i = 0; i < stamps.size(); ++i) {
    const int64_t d = stamps[i] > t ? stamps[i] - t : t - stamps[i];
    if (d < best_diff) {
      best_diff = d;
      best = static_cast<long>(i);
    }
  }
  return best >= 0 && best_diff <= max_diff ? best : -1;
}

Eigen::Isometry3d to_iso(const Eigen::Quaterniond& q, const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = p;
  return T;
}

}  // namespace

IndexPairs associate_by_time(const Trajectory& gt, const Trajectory& est, int64_t max_diff_ns) {
  // Match the shorter trajectory into the longer one so that none of its poses is lost.
  const bool est_longer = est.size() > gt.size();
  const Trajectory& shorter = est_longer ? gt : est;
  const Trajectory& longer = est_longer ? est : gt;
  std::vector<int64_t> stamps(longer.size());
  for (size_t i = 0; i < longer.size(); ++i) stamps[i] = longer[i].stamp_ns;
  const bool sorted = std::is_sorted(stamps.begin(), stamps.end());

  IndexPairs pairs;
  for (size_t i = 0; i < shorter.size(); ++i) {
    const int64_t t = shorter[i].stamp_ns;
    const long j =
        sorted ? nearest_sorted(stamps, t, max_diff_ns) : nearest_linear(stamps, t, max_diff_ns);
    if (j < 0) continue;
    if (est_longer) {
      pairs.emplace_back(i, static_cast<size_t>(j));
    } else {
      pairs.emplace_back(static_cast<size_t>(j), i);
    }
  }
  return pairs;
}

IndexPairs associate_by_index(const Trajectory& gt, const Trajectory& est) {
  IndexPairs pairs;
  const size_t n = std::min(gt.size(), est.size());
  pairs.reserve(n);
  for (size_t i = 0; i < n; ++i) pairs.emplace_back(i, i);
  return pairs;
}

bool umeyama_align(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                   Alignment mode, Sim3Transform& out) {
  out = Sim3Transform();
  if (mode == Alignment::kNone) return true;
  const size_t n = src.size();
  if (n < 3 || dst.size() != n) return false;

  // Umeyama 1991, eqs. 34-43.
  Eigen::Vector3d mean_src = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_dst = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_src += src[i];
    mean_dst += dst[i];
  }
  mean_src /= static_cast<double>(n);
  mean_dst /= static_cast<double>(n);
  double var_src = 0.0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = src[i] - mean_src;
    var_src += a.squaredNorm();
    cov += (dst[i] - mean_dst) * a.transpose();
  }
  var_src /= static_cast<double>(n);
  cov /= static_cast<double>(n);

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();
  // Rank < 2 (all points equal or on one point per side): the rotation is undetermined.
  if (!(d(0) > 0.0) || !(d(1) > d(0) * 1e-14)) return false;
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  out.R = svd.matrixU() * S * svd.matrixV().transpose();
  out.scale = mode == Alignment::kSim3 ? (d.asDiagonal() * S).trace() / var_src : 1.0;
  out.t = mean_dst - out.scale * out.R * mean_src;
  return true;
}

ErrorStats compute_stats(const std::vector<double>& errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  double sum = 0.0;
  double sum_sq = 0.0;
  s.max = errors.front();
  s.min = errors.front();
  for (double e : errors) {
    sum += e;
    sum_sq += e * e;
    s.max = std::max(s.max, e);
    s.min = std::min(s.min, e);
  }
  const double n = static_cast<double>(errors.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0.0;
  for (double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  const size_t m = sorted.size() / 2;
  s.median = sorted.size() % 2 ? sorted[m] : 0.5 * (sorted[m - 1] + sorted[m]);
  return s;
}

EvalResult evaluate_trajectories(const Trajectory& gt, const Trajectory& est,
                                 const EvalParams& params) {
  EvalResult r;
  r.gt_poses = gt.size();
  r.est_poses = est.size();
  if (params.rpe_delta < 1) {
    r.error = "RPE delta must be at least 1 frame";
    return r;
  }
  r.pairs = params.by_index ? associate_by_index(gt, est)
                            : associate_by_time(gt, est, params.max_diff_ns);
  if (r.pairs.empty()) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "no pose of the estimate has a ground-truth stamp within %g s",
                  params.max_diff_ns * 1e-9);
    r.error = params.by_index ? "a trajectory is empty" : buf;
    return r;
  }
  const size_t n = r.pairs.size();
  std::vector<Eigen::Vector3d> p_est(n);
  r.gt_positions.resize(n);
  r.stamps_ns.resize(n);
  for (size_t k = 0; k < n; ++k) {
    r.gt_positions[k] = gt[r.pairs[k].first].p_world_cam;
    p_est[k] = est[r.pairs[k].second].p_world_cam;
    r.stamps_ns[k] = gt[r.pairs[k].first].stamp_ns;
  }
  if (!umeyama_align(p_est, r.gt_positions, params.align, r.alignment)) {
    r.error = n < 3 ? "alignment " + std::string(to_string(params.align)) + " needs at least 3 " +
                          "associated poses, found " + std::to_string(n)
                    : "alignment " + std::string(to_string(params.align)) +
                          " is degenerate (the estimated positions lie on one line or one point)";
    return r;
  }

  r.est_positions_aligned.resize(n);
  r.ate_errors_m.resize(n);
  for (size_t k = 0; k < n; ++k) {
    r.est_positions_aligned[k] = r.alignment.apply(p_est[k]);
    r.ate_errors_m[k] = (r.gt_positions[k] - r.est_positions_aligned[k]).norm();
    if (k > 0) r.gt_path_length_m += (r.gt_positions[k] - r.gt_positions[k - 1]).norm();
  }
  r.ate_m = compute_stats(r.ate_errors_m);
  if (r.gt_path_length_m > 0.0) {
    const double f = 100.0 / r.gt_path_length_m;
    std::vector<double> pct(n);
    for (size_t k = 0; k < n; ++k) pct[k] = r.ate_errors_m[k] * f;
    r.ate_pct_path = compute_stats(pct);
  }

  // RPE over consecutive pairs (0, d), (d, 2d), ... of the associated, aligned poses.
  const Eigen::Quaterniond q_align(r.alignment.R);
  std::vector<double> rpe_t;
  std::vector<double> rpe_r;
  const size_t delta = static_cast<size_t>(params.rpe_delta);
  for (size_t i = 0; i + delta < n; i += delta) {
    const size_t j = i + delta;
    const Eigen::Isometry3d gi = to_iso(gt[r.pairs[i].first].q_world_cam, r.gt_positions[i]);
    const Eigen::Isometry3d gj = to_iso(gt[r.pairs[j].first].q_world_cam, r.gt_positions[j]);
    const Eigen::Isometry3d ei =
        to_iso(q_align * est[r.pairs[i].second].q_world_cam, r.est_positions_aligned[i]);
    const Eigen::Isometry3d ej =
        to_iso(q_align * est[r.pairs[j].second].q_world_cam, r.est_positions_aligned[j]);
    const Eigen::Isometry3d E = (gi.inverse() * gj).inverse() * (ei.inverse() * ej);
    rpe_t.push_back(E.translation().norm());
    rpe_r.push_back(Eigen::AngleAxisd(Eigen::Quaterniond(E.linear()).normalized()).angle() * 180.0 /
                    M_PI);
  }
  r.rpe_trans_m = compute_stats(rpe_t);
  r.rpe_rot_deg = compute_stats(rpe_r);
  r.ok = true;
  return r;
}

}  // namespace rdslam
