#include "core/parsac.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/pose_refine.h"

namespace rdslam {

// ---------------------------------------------------------------------------------------------
// Parameters

void ParsacParams::visit(ParamVisitor& v) {
  v.field("method", method, {"ransac", "lo-ransac", "arsac", "parsac", "magsac-ref"},
          "robust estimator (Sec. 5; magsac-ref is OpenCV's, allocates)");
  v.field("solver", solver, {"dlt6", "p3p"},
          "minimal solver: dlt6 = paper's projective matrix (m=6), p3p = calibrated (m=4)");
  v.field("bins_x", bins_x, 1, 64, "image bins across (Sec. 5: 10)");
  v.field("bins_y", bins_y, 1, 64, "image bins down (Sec. 5: 10)");
  v.field("prior_min", prior_min, 0.0, 1.0, "lower truncation of the bin inlier-ratio prior");
  v.field("prior_max", prior_max, 0.0, 1.0, "upper truncation of the bin inlier-ratio prior");
  v.field("eta", eta, 1e-9, 0.5, "termination: stop when (1 - (sum p_i eps_i)^m)^K < eta");
  v.field("max_iterations", max_iterations, 1, 1000000, "hypothesis budget per frame");
  v.field("min_iterations", min_iterations, 0, 1000000, "hypotheses drawn at least");
  v.field("inlier_threshold_px", inlier_threshold_px, 0.1, 100.0,
          "reprojection error of an inlier in pixels");
  v.field("min_inliers", min_inliers, 3, 100000, "fewer final inliers means no model");
  v.field("refine_iterations", refine_iterations, 0, 100,
          "Levenberg-Marquardt iterations of eq. (1) per refinement round");
  v.field("lo_inner_iterations", lo_inner_iterations, 0, 1000,
          "lo-ransac: inner non-minimal samples per local optimisation");
  v.field("seed", seed, 0, INT_MAX, "random seed; same seed, same result");
}

std::string ParsacParams::validate() const {
  RobustMethod m;
  MinimalSolver s;
  if (!parse_robust_method(method, &m)) return "parsac.method: unknown value '" + method + "'";
  if (!parse_minimal_solver(solver, &s)) return "parsac.solver: unknown value '" + solver + "'";
  if (!(prior_min > 0.0) || prior_min > prior_max) {
    return "parsac.prior_min: must be > 0 and <= parsac.prior_max (" + std::to_string(prior_max) +
           ")";
  }
  if (min_iterations > max_iterations) {
    return "parsac.min_iterations: must be <= parsac.max_iterations (" +
           std::to_string(max_iterations) + ")";
  }
  if (!(eta > 0.0 && eta < 1.0)) return "parsac.eta: must lie in (0, 1)";
  if (bins_x * bins_y < sample_size(s)) {
    return "parsac.bins_x * parsac.bins_y: fewer bins than the sample size of solver " + solver;
  }
  return {};
}

bool parse_robust_method(const std::string& name, RobustMethod* out) {
  static const struct {
    const char* name;
    RobustMethod m;
  } kTable[] = {{"ransac", RobustMethod::kRansac},
                {"lo-ransac", RobustMethod::kLoRansac},
                {"arsac", RobustMethod::kArsac},
                {"parsac", RobustMethod::kParsac},
                {"magsac-ref", RobustMethod::kMagsacRef}};
  for (const auto& e : kTable) {
    if (name == e.name) {
      *out = e.m;
      return true;
    }
  }
  return false;
}

bool parse_minimal_solver(const std::string& name, MinimalSolver* out) {
  if (name == "dlt6") {
    *out = MinimalSolver::kDlt6;
  } else if (name == "p3p") {
    *out = MinimalSolver::kP3P;
  } else {
    return false;
  }
  return true;
}

const char* to_string(RobustMethod m) {
  switch (m) {
    case RobustMethod::kRansac:
      return "ransac";
    case RobustMethod::kLoRansac:
      return "lo-ransac";
    case RobustMethod::kArsac:
      return "arsac";
    case RobustMethod::kParsac:
      return "parsac";
    case RobustMethod::kMagsacRef:
      return "magsac-ref";
  }
  return "?";
}

const char* to_string(MinimalSolver s) {
  return s == MinimalSolver::kDlt6 ? "dlt6" : "p3p";
}

int sample_size(MinimalSolver s) {
  return s == MinimalSolver::kDlt6 ? 6 : 4;
}

const char* to_string(PoseStatus s) {
  switch (s) {
    case PoseStatus::kOk:
      return "ok";
    case PoseStatus::kTooFewPoints:
      return "too-few-points";
    case PoseStatus::kNoModel:
      return "no-model";
    case PoseStatus::kBadInput:
      return "bad-input";
  }
  return "?";
}

// ---------------------------------------------------------------------------------------------
// Sec. 5 formulas

bool weighted_covariance(const Eigen::Vector2d* x, const double* w, int n, Eigen::Matrix2d* C) {
  double sw = 0.0, sw2 = 0.0;
  Eigen::Vector2d sx(0, 0);
  for (int i = 0; i < n; ++i) {
    if (!(w[i] > 0.0)) continue;
    sw += w[i];
    sw2 += w[i] * w[i];
    sx += w[i] * x[i];
  }
  const double denom = sw * sw - sw2;
  if (!(sw > 0.0) || !(denom > 1e-12 * sw * sw)) return false;
  const Eigen::Vector2d mean = sx / sw;
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  for (int i = 0; i < n; ++i) {
    if (!(w[i] > 0.0)) continue;
    const Eigen::Vector2d d = x[i] - mean;
    S.noalias() += w[i] * d * d.transpose();
  }
  // Eq. (4): C = sum(eps) / ((sum eps)^2 - sum eps^2) * sum eps_i (x_i - x̄)(x_i - x̄)^T.
  *C = (sw / denom) * S;
  return true;
}

Eigen::Matrix2d sample_covariance(const Eigen::Vector2d* x, int n) {
  Eigen::Vector2d mean(0, 0);
  for (int i = 0; i < n; ++i) mean += x[i];
  mean /= n;
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  for (int i = 0; i < n; ++i) S.noalias() += (x[i] - mean) * (x[i] - mean).transpose();
  return S / (n - 1);  // eq. (3)
}

double parsac_score(double sum_eps, const Eigen::Matrix2d& C, double image_area) {
  const double det = std::max(0.0, C.determinant());    // round-off can make it slightly < 0
  return sum_eps * M_PI * std::sqrt(det) / image_area;  // eq. (5)
}

int required_iterations(double q, int m, double eta) {
  if (q >= 1.0) return 1;
  if (!(q > 0.0)) return INT_MAX;
  const double good = std::pow(q, m);  // probability that a sample holds no outlier
  if (!(good > 0.0)) return INT_MAX;
  // (1 - good)^K < eta  <=>  K > log(eta) / log(1 - good); log1p keeps tiny `good` exact.
  const double k = std::log(eta) / std::log1p(-good);
  if (!(k < static_cast<double>(INT_MAX) - 1.0)) return INT_MAX;
  int K = static_cast<int>(std::floor(k)) + 1;
  // Guard the boundary against round-off in the division.
  while (K > 1 && std::pow(1.0 - good, K - 1) < eta) --K;
  while (!(std::pow(1.0 - good, K) < eta) && K < INT_MAX) ++K;
  return K;
}

void truncated_prior_probabilities(const double* prior, const uint8_t* occupied, int n, double lo,
                                   double hi, double* p) {
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    p[i] = occupied[i] ? std::min(hi, std::max(lo, prior[i])) : 0.0;
    sum += p[i];
  }
  for (int i = 0; i < n; ++i) p[i] = sum > 0.0 ? p[i] / sum : 0.0;
}

// ---------------------------------------------------------------------------------------------
// Estimator

RobustPoseEstimator::RobustPoseEstimator(const ParsacParams& params, const CameraModel& camera,
                                         int max_points)
    : params_(params) {
  const std::string err = params.validate();
  if (!err.empty()) throw std::invalid_argument(err);
  if (max_points < 1) throw std::invalid_argument("RobustPoseEstimator: max_points must be >= 1");
  parse_robust_method(params.method, &method_);
  parse_minimal_solver(params.solver, &solver_);
  K_.fx = camera.fx;
  K_.fy = camera.fy;
  K_.cx = camera.cx;
  K_.cy = camera.cy;
  width_ = camera.width;
  height_ = camera.height;
  bins_x_ = params.bins_x;
  bins_y_ = params.bins_y;
  max_points_ = max_points;
  m_ = sample_size(solver_);
  const int B = bin_count();
  point_bin_.assign(max_points, -1);
  valid_idx_.assign(max_points, 0);
  valid_bin_.assign(max_points, 0);
  soa_.assign(5 * static_cast<size_t>(max_points), 0.0);
  flags_.assign(max_points, 0);
  bin_points_.assign(max_points, 0);
  inlier_idx_.assign(max_points, 0);
  mask_a_.assign(max_points, 0);
  mask_b_.assign(max_points, 0);
  bearing_.assign(max_points, Eigen::Vector3d::Zero());
  bin_start_.assign(B + 1, 0);
  bin_size_.assign(B, 0);
  occupied_.assign(B, 0);
  cumulative_.assign(B, 0.0);
  prior_.assign(B, params.prior_max);
  probs_.assign(B, 0.0);
  best_eps_.assign(B, 0.0);
  bins_scratch_.assign(B, 0);
  best_bins_.assign(B, 0);
  occ_centre_.assign(B, Eigen::Vector2d::Zero());
  occ_weight_.assign(B, 0.0);
  occ_flag_.assign(B, 0);
  bin_centre_.resize(B);
  for (int by = 0; by < bins_y_; ++by) {
    for (int bx = 0; bx < bins_x_; ++bx) {
      bin_centre_[by * bins_x_ + bx] =
          Eigen::Vector2d((bx + 0.5) * width_ / bins_x_, (by + 0.5) * height_ / bins_y_);
    }
  }
  reseed(static_cast<uint64_t>(params.seed));
}

void RobustPoseEstimator::reset_prior() {
  std::fill(prior_.begin(), prior_.end(), params_.prior_max);
}

void RobustPoseEstimator::reseed(uint64_t seed) {
  // splitmix64 expands the seed into the xoshiro256** state (Blackman & Vigna).
  uint64_t z = seed;
  for (auto& s : rng_) {
    z += 0x9e3779b97f4a7c15ULL;
    uint64_t x = z;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    s = x ^ (x >> 31);
  }
}

uint64_t RobustPoseEstimator::next_u64() {
  auto rotl = [](uint64_t x, int k) { return (x << k) | (x >> (64 - k)); };
  const uint64_t result = rotl(rng_[1] * 5, 7) * 9;
  const uint64_t t = rng_[1] << 17;
  rng_[2] ^= rng_[0];
  rng_[3] ^= rng_[1];
  rng_[1] ^= rng_[2];
  rng_[0] ^= rng_[3];
  rng_[2] ^= t;
  rng_[3] = rotl(rng_[3], 45);
  return result;
}

double RobustPoseEstimator::next_double() {
  return static_cast<double>(next_u64() >> 11) * (1.0 / 9007199254740992.0);
}

int RobustPoseEstimator::next_int(int n) {
  // Lemire's multiply-shift; the bias (< n / 2^32) is far below anything measurable here.
  return static_cast<int>(((next_u64() >> 32) * static_cast<uint64_t>(n)) >> 32);
}

int RobustPoseEstimator::bin_of(double u, double v) const {
  int bx = static_cast<int>(std::floor(u * bins_x_ / width_));
  int by = static_cast<int>(std::floor(v * bins_y_ / height_));
  bx = std::min(bins_x_ - 1, std::max(0, bx));
  by = std::min(bins_y_ - 1, std::max(0, by));
  return by * bins_x_ + bx;
}

bool RobustPoseEstimator::draw_sample(int* idx) {
  if (method_ == RobustMethod::kRansac || method_ == RobustMethod::kLoRansac) {
    for (int k = 0; k < m_; ++k) {
      int j;
      bool dup;
      do {
        j = valid_idx_[next_int(n_valid_)];
        dup = false;
        for (int q = 0; q < k; ++q) dup = dup || idx[q] == j;
      } while (dup);
      idx[k] = j;
    }
    return true;
  }
  // Sec. 5: m distinct bins drawn with probabilities p_i (rejecting repeats is sampling from the
  // renormalised remaining bins), then one point uniformly inside each bin.
  const double total = cumulative_[n_occupied_ - 1];
  int chosen[16];
  for (int k = 0; k < m_; ++k) {
    int attempts = 0;
    int pos;
    bool dup;
    do {
      const double u = next_double() * total;
      pos = static_cast<int>(
          std::upper_bound(cumulative_.begin(), cumulative_.begin() + n_occupied_, u) -
          cumulative_.begin());
      pos = std::min(pos, n_occupied_ - 1);
      dup = false;
      for (int q = 0; q < k; ++q) dup = dup || chosen[q] == pos;
    } while (dup && ++attempts < 10000);
    if (dup) return false;
    chosen[k] = pos;
    const int b = occupied_[pos];
    idx[k] = bin_points_[bin_start_[b] + next_int(bin_size_[b])];
  }
  return true;
}

bool RobustPoseEstimator::make_hypotheses(const int* idx, int* n_hyp) {
  *n_hyp = 0;
  if (solver_ == MinimalSolver::kDlt6) {
    if (!solve_dlt(px_, pw_, idx, 6, K_, world_centre_, world_scale_, &hyp_[0])) return false;
    *n_hyp = 1;
    return true;
  }
  const Eigen::Vector3d f[3] = {bearing_[idx[0]], bearing_[idx[1]], bearing_[idx[2]]};
  const Eigen::Vector3d X[3] = {pw_[idx[0]], pw_[idx[1]], pw_[idx[2]]};
  Eigen::Matrix3d R[4];
  Eigen::Vector3d t[4];
  const int ns = solve_p3p(f, X, R, t);
  // The fourth point of the sample picks the solution (it must lie in front of the camera).
  int best = -1;
  double best_err = std::numeric_limits<double>::infinity();
  const Eigen::Vector3d& X4 = pw_[idx[3]];
  const Eigen::Vector2d& x4 = px_[idx[3]];
  for (int s = 0; s < ns; ++s) {
    const Eigen::Vector3d Xc = R[s] * X4 + t[s];
    if (!(Xc.z() > 0.0)) continue;
    const double du = K_.fx * Xc.x() / Xc.z() + K_.cx - x4.x();
    const double dv = K_.fy * Xc.y() / Xc.z() + K_.cy - x4.y();
    const double e = du * du + dv * dv;
    if (e < best_err) {
      best_err = e;
      best = s;
    }
  }
  if (best < 0) return false;
  hyp_[0] = compose_projection(K_, R[best], t[best]);
  *n_hyp = 1;
  return true;
}

double RobustPoseEstimator::evaluate(const Mat34& P, int* bin_inliers, int* total_inliers) {
  for (int k = 0; k < n_occupied_; ++k) bin_inliers[occupied_[k]] = 0;
  const double th2 = params_.inlier_threshold_px * params_.inlier_threshold_px;
  const double p00 = P(0, 0), p01 = P(0, 1), p02 = P(0, 2), p03 = P(0, 3);
  const double p10 = P(1, 0), p11 = P(1, 1), p12 = P(1, 2), p13 = P(1, 3);
  const double p20 = P(2, 0), p21 = P(2, 1), p22 = P(2, 2), p23 = P(2, 3);
  int total = 0;
  const double* xs = soa_.data();  // X, Y, Z, u, v of the usable points (contiguous columns)
  const double* ys = xs + max_points_;
  const double* zs = ys + max_points_;
  const double* us = zs + max_points_;
  const double* vs = us + max_points_;
  const int* bins = valid_bin_.data();
  uint8_t* flag = flags_.data();
  // Two passes: a branch-free loop the compiler vectorises (the hot spot of every method), then
  // the per-bin counts. Points behind the camera (w <= 0) are never inliers.
  for (int k = 0; k < n_valid_; ++k) {
    const double X = xs[k], Y = ys[k], Z = zs[k];
    const double w = p20 * X + p21 * Y + p22 * Z + p23;
    const double du = (p00 * X + p01 * Y + p02 * Z + p03) - us[k] * w;
    const double dv = (p10 * X + p11 * Y + p12 * Z + p13) - vs[k] * w;
    // |x - P X / w|^2 < th^2  <=>  du^2 + dv^2 < th^2 w^2 for w > 0 (no division needed).
    flag[k] = static_cast<uint8_t>((w > 0.0) & (du * du + dv * dv < th2 * w * w));
  }
  for (int k = 0; k < n_valid_; ++k) {
    bin_inliers[bins[k]] += flag[k];
    total += flag[k];
  }
  *total_inliers = total;
  return score_of(bin_inliers, total);
}

double RobustPoseEstimator::score_of(const int* bin_inliers, int total_inliers) {
  if (method_ != RobustMethod::kArsac && method_ != RobustMethod::kParsac) {
    return static_cast<double>(total_inliers);
  }
  // Sec. 5: each occupied bin is represented by its centre, weighted by its inlier ratio.
  double sum_eps = 0.0;
  for (int k = 0; k < n_occupied_; ++k) {
    const int b = occupied_[k];
    occ_weight_[k] = static_cast<double>(bin_inliers[b]) / bin_size_[b];
    sum_eps += occ_weight_[k];
  }
  Eigen::Matrix2d C;
  if (!weighted_covariance(occ_centre_.data(), occ_weight_.data(), n_occupied_, &C)) return 0.0;
  return parsac_score(sum_eps, C, static_cast<double>(width_) * height_);
}

double RobustPoseEstimator::inlier_probability(const int* bin_inliers, int total_inliers) const {
  if (method_ != RobustMethod::kArsac && method_ != RobustMethod::kParsac) {
    return n_valid_ > 0 ? static_cast<double>(total_inliers) / n_valid_ : 0.0;
  }
  double q = 0.0;  // Sec. 5: probability of drawing an inlier = sum_i p_i eps^_i
  for (int k = 0; k < n_occupied_; ++k) {
    const int b = occupied_[k];
    q += probs_[b] * static_cast<double>(bin_inliers[b]) / bin_size_[b];
  }
  return q;
}

int RobustPoseEstimator::collect_inliers(const Mat34& P, double threshold_px, uint8_t* mask) const {
  const double th2 = threshold_px * threshold_px;
  int total = 0;
  for (int i = 0; i < n_; ++i) mask[i] = 0;
  for (int k = 0; k < n_valid_; ++k) {
    const int i = valid_idx_[k];
    const Eigen::Vector3d h = P.leftCols<3>() * pw_[i] + P.col(3);
    if (!(h.z() > 0.0)) continue;
    const double du = h.x() / h.z() - px_[i].x(), dv = h.y() / h.z() - px_[i].y();
    if (du * du + dv * dv < th2) {
      mask[i] = 1;
      ++total;
    }
  }
  return total;
}

void RobustPoseEstimator::local_optimise(Mat34* P_best, double* best_score, int* best_bins,
                                         int* best_total) {
  // LO-RANSAC (Chum, Matas, Kittler, DAGM 2003), "inner RANSAC with iteration": non-minimal
  // samples drawn from the inliers of the new best model are fitted by minimising eq. (1), then
  // the best of them is refitted on all its inliers with a shrinking threshold.
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  if (!decompose_projection(*P_best, K_, &R, &t)) return;
  const double th = params_.inlier_threshold_px;
  int n_inl = collect_inliers(*P_best, th, mask_a_.data());
  int k = 0;
  for (int i = 0; i < n_; ++i) {
    if (mask_a_[i]) inlier_idx_[k++] = i;
  }
  const int sample = std::min(n_inl, std::max(2 * m_, 12));
  Eigen::Matrix3d R_best = R;
  Eigen::Vector3d t_best = t;
  bool improved = false;
  if (n_inl > sample) {
    for (int r = 0; r < params_.lo_inner_iterations; ++r) {
      for (int s = 0; s < sample; ++s) {  // partial Fisher-Yates over the inlier list
        const int j = s + next_int(n_inl - s);
        std::swap(inlier_idx_[s], inlier_idx_[j]);
        mask_b_[inlier_idx_[s]] = 1;
      }
      Eigen::Matrix3d Rr = R;
      Eigen::Vector3d tr = t;
      refine_pose(px_, pw_, mask_b_.data(), n_, K_, 5, &Rr, &tr);
      for (int s = 0; s < sample; ++s) mask_b_[inlier_idx_[s]] = 0;
      int total = 0;
      const Mat34 P = compose_projection(K_, Rr, tr);
      const double sc = evaluate(P, bins_scratch_.data(), &total);
      if (sc > *best_score) {
        *best_score = sc;
        *best_total = total;
        *P_best = P;
        std::copy(bins_scratch_.begin(), bins_scratch_.end(), best_bins);
        R_best = Rr;
        t_best = tr;
        improved = true;
      }
    }
  }
  // Iterative least squares on all inliers, threshold 2x -> 1x.
  const double mult[3] = {2.0, 1.5, 1.0};
  for (double mu : mult) {
    Eigen::Matrix3d Rr = R_best;
    Eigen::Vector3d tr = t_best;
    n_inl = collect_inliers(compose_projection(K_, Rr, tr), mu * th, mask_a_.data());
    if (n_inl < m_) break;
    refine_pose(px_, pw_, mask_a_.data(), n_, K_, 5, &Rr, &tr);
    int total = 0;
    const Mat34 P = compose_projection(K_, Rr, tr);
    const double sc = evaluate(P, bins_scratch_.data(), &total);
    if (sc > *best_score) {
      *best_score = sc;
      *best_total = total;
      *P_best = P;
      std::copy(bins_scratch_.begin(), bins_scratch_.end(), best_bins);
      R_best = Rr;
      t_best = tr;
      improved = true;
    }
  }
  (void)improved;
}

void RobustPoseEstimator::finish(const Mat34& P_best, bool refit_dlt, uint8_t* inlier_mask,
                                 PoseEstimate* result) {
  const double th = params_.inlier_threshold_px;
  int n_inl = collect_inliers(P_best, th, mask_a_.data());
  // Sec. 5: "the projective matrix is further refined with all inliers. Finally, we decompose
  // the estimated projective matrix to R and T, and then refine them by minimizing (1)."
  Mat34 P = P_best;
  if (refit_dlt && n_inl >= 6) {
    int k = 0;
    for (int i = 0; i < n_; ++i) {
      if (mask_a_[i]) inlier_idx_[k++] = i;
    }
    Mat34 P_all;
    if (solve_dlt(px_, pw_, inlier_idx_.data(), k, K_, world_centre_, world_scale_, &P_all)) {
      P = P_all;
    }
  }
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  if (!decompose_projection(P, K_, &R, &t) && !decompose_projection(P_best, K_, &R, &t)) {
    result->status = PoseStatus::kNoModel;
    return;
  }
  // Two rounds: refine over the inliers, then re-classify with the refined pose.
  for (int round = 0; round < 2; ++round) {
    if (n_inl >= 3)
      refine_pose(px_, pw_, mask_a_.data(), n_, K_, params_.refine_iterations, &R, &t);
    n_inl = collect_inliers(compose_projection(K_, R, t), th, mask_a_.data());
  }
  double sq = 0.0;
  const Mat34 Pf = compose_projection(K_, R, t);
  for (int k = 0; k < n_occupied_; ++k) bins_scratch_[occupied_[k]] = 0;
  for (int i = 0; i < n_; ++i) {
    if (!mask_a_[i]) continue;
    const Eigen::Vector3d h = Pf.leftCols<3>() * pw_[i] + Pf.col(3);
    sq += (h.head<2>() / h.z() - px_[i]).squaredNorm();
    ++bins_scratch_[point_bin_[i]];
  }
  result->T_cam_world.linear() = R;
  result->T_cam_world.translation() = t;
  result->inlier_count = n_inl;
  result->rms_error_px = n_inl > 0 ? std::sqrt(sq / n_inl) : 0.0;
  if (inlier_mask) std::copy(mask_a_.begin(), mask_a_.begin() + n_, inlier_mask);
  if (n_inl < std::max(params_.min_inliers, m_)) {
    result->status = PoseStatus::kNoModel;
    return;
  }
  result->status = PoseStatus::kOk;
  // Sec. 5: record each bin's inlier ratio for the next frame's sampling, truncated to
  // [prior_min, prior_max]. Bins without points this frame keep what they had.
  for (int k = 0; k < n_occupied_; ++k) {
    const int b = occupied_[k];
    const double ratio = static_cast<double>(bins_scratch_[b]) / bin_size_[b];
    prior_[b] = std::min(params_.prior_max, std::max(params_.prior_min, ratio));
  }
}

PoseStatus RobustPoseEstimator::estimate(const Eigen::Vector2d* pixels,
                                         const Eigen::Vector3d* p_world, int count,
                                         const Eigen::Isometry3d* T_cam_world_guess,
                                         uint8_t* inlier_mask, PoseEstimate* result) {
  if (!result) return PoseStatus::kBadInput;
  *result = PoseEstimate();
  if (T_cam_world_guess) result->T_cam_world = *T_cam_world_guess;
  if (count < 0 || count > max_points_ || (count > 0 && (!pixels || !p_world))) {
    result->status = PoseStatus::kBadInput;
    return result->status;
  }
  if (inlier_mask) std::fill(inlier_mask, inlier_mask + count, 0);
  px_ = pixels;
  pw_ = p_world;
  n_ = count;

  // Points -> bins (counting sort), usable points, world normalisation for the DLT.
  const int B = bin_count();
  std::fill(bin_size_.begin(), bin_size_.end(), 0);
  n_valid_ = 0;
  Eigen::Vector3d centre(0, 0, 0);
  for (int i = 0; i < n_; ++i) {
    const Eigen::Vector2d& x = px_[i];
    const Eigen::Vector3d& X = pw_[i];
    if (!std::isfinite(x.x() + x.y() + X.x() + X.y() + X.z())) {
      point_bin_[i] = -1;
      continue;
    }
    point_bin_[i] = bin_of(x.x(), x.y());
    ++bin_size_[point_bin_[i]];
    valid_idx_[n_valid_++] = i;
    centre += X;
    bearing_[i] =
        Eigen::Vector3d((x.x() - K_.cx) / K_.fx, (x.y() - K_.cy) / K_.fy, 1.0).normalized();
  }
  bin_start_[0] = 0;
  n_occupied_ = 0;
  for (int b = 0; b < B; ++b) {
    bin_start_[b + 1] = bin_start_[b] + bin_size_[b];
    occ_flag_[b] = bin_size_[b] > 0;
    if (bin_size_[b] > 0) {
      occ_centre_[n_occupied_] = bin_centre_[b];
      occupied_[n_occupied_++] = b;
    }
  }
  for (int b = 0; b < B; ++b) bins_scratch_[b] = bin_start_[b];
  for (int k = 0; k < n_valid_; ++k) {
    const int i = valid_idx_[k];
    bin_points_[bins_scratch_[point_bin_[i]]++] = i;
    valid_bin_[k] = point_bin_[i];
    soa_[k] = pw_[i].x();
    soa_[max_points_ + k] = pw_[i].y();
    soa_[2 * max_points_ + k] = pw_[i].z();
    soa_[3 * max_points_ + k] = px_[i].x();
    soa_[4 * max_points_ + k] = px_[i].y();
  }
  if (n_valid_ > 0) centre /= n_valid_;
  double spread = 0.0;
  for (int k = 0; k < n_valid_; ++k) spread += (pw_[valid_idx_[k]] - centre).norm();
  world_centre_ = centre;
  world_scale_ = n_valid_ > 0 && spread > 0.0 ? spread / n_valid_ : 1.0;

  const bool bin_sampler = method_ == RobustMethod::kArsac || method_ == RobustMethod::kParsac;
  if (n_valid_ < m_ || (bin_sampler && n_occupied_ < m_)) {
    result->status = PoseStatus::kTooFewPoints;
    return result->status;
  }
  if (method_ == RobustMethod::kMagsacRef) return estimate_magsac(inlier_mask, result);

  // Bin sampling probabilities: PARSAC's truncated prior, ARSAC's uniform distribution.
  if (method_ == RobustMethod::kParsac) {
    truncated_prior_probabilities(prior_.data(), occ_flag_.data(), B, params_.prior_min,
                                  params_.prior_max, probs_.data());
  } else {
    for (int b = 0; b < B; ++b) probs_[b] = occ_flag_[b] ? 1.0 / n_occupied_ : 0.0;
  }
  double acc = 0.0;
  for (int k = 0; k < n_occupied_; ++k) {
    acc += probs_[occupied_[k]];
    cumulative_[k] = acc;
  }

  Mat34 P_best = Mat34::Zero();
  double best_score = -1.0;
  int best_total = 0;
  bool have_best = false;
  int K_required = INT_MAX;
  auto accept = [&](const Mat34& P, double score, int total, int iteration) {
    P_best = P;
    best_score = score;
    best_total = total;
    have_best = true;
    result->best_iteration = iteration;
    std::copy(bins_scratch_.begin(), bins_scratch_.end(), best_bins_.begin());
    if (method_ == RobustMethod::kLoRansac) {
      local_optimise(&P_best, &best_score, best_bins_.data(), &best_total);
    }
    K_required =
        required_iterations(inlier_probability(best_bins_.data(), best_total), m_, params_.eta);
  };
  if (T_cam_world_guess) {
    const Mat34 P =
        compose_projection(K_, T_cam_world_guess->linear(), T_cam_world_guess->translation());
    int total = 0;
    const double sc = evaluate(P, bins_scratch_.data(), &total);
    if (total > 0) accept(P, sc, total, 0);
  }
  int idx[16];
  int it = 0;
  while (it < params_.max_iterations && (it < params_.min_iterations || it < K_required)) {
    ++it;
    if (!draw_sample(idx)) continue;
    if (observer_) observer_(observer_ctx_, idx, m_);
    int nh = 0;
    if (!make_hypotheses(idx, &nh)) continue;
    for (int h = 0; h < nh; ++h) {
      int total = 0;
      const double sc = evaluate(hyp_[h], bins_scratch_.data(), &total);
      if (total >= m_ && sc > best_score) accept(hyp_[h], sc, total, it);
    }
  }
  result->iterations = it;
  result->required_iterations = K_required;
  result->score = best_score;
  for (int b = 0; b < B; ++b) {
    best_eps_[b] =
        have_best && bin_size_[b] > 0 ? static_cast<double>(best_bins_[b]) / bin_size_[b] : 0.0;
  }
  if (!have_best) {
    result->status = PoseStatus::kNoModel;
    return result->status;
  }
  finish(P_best, solver_ == MinimalSolver::kDlt6, inlier_mask, result);
  return result->status;
}

PoseStatus RobustPoseEstimator::estimate_magsac(uint8_t* inlier_mask, PoseEstimate* result) {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  if (!opencv_magsac_pnp(px_, pw_, n_, K_, params_.max_iterations, params_.inlier_threshold_px,
                         1.0 - params_.eta, params_.seed, &R, &t, nullptr)) {
    result->status = PoseStatus::kNoModel;
    return result->status;
  }
  // OpenCV does not report its iteration count; the same final stage as our methods follows.
  finish(compose_projection(K_, R, t), false, inlier_mask, result);
  return result->status;
}

}  // namespace rdslam
