#include "core/initializer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "core/log.h"

namespace rdslam {

const char* to_string(InitStatus s) {
  switch (s) {
    case InitStatus::kOk:
      return "ok";
    case InitStatus::kNoReference:
      return "no-reference";
    case InitStatus::kFewMatches:
      return "few-matches";
    case InitStatus::kLittleMotion:
      return "little-motion";
    case InitStatus::kModelFailed:
      return "model-failed";
    case InitStatus::kAmbiguous:
      return "ambiguous";
    case InitStatus::kLowParallax:
      return "low-parallax";
    case InitStatus::kInconsistent:
      return "inconsistent";
    case InitStatus::kFewPoints:
      return "few-points";
    case InitStatus::kFastMotion:
      return "fast-motion";
  }
  return "?";
}

void InitializerParams::visit(ParamVisitor& v) {
  v.field("min_features", min_features, 10, 10000, "frames with fewer features are skipped");
  v.field("min_matches", min_matches, 10, 10000, "matches to the reference frame needed");
  v.field("search_radius_frac", search_radius_frac, 0.01, 1.0,
          "match window radius, fraction of image width");
  v.field("min_median_flow_frac", min_median_flow_frac, 0.0, 1.0,
          "motion gate: median match displacement, fraction of image width");
  v.field("homography_ratio", homography_ratio, 0.0, 1.0,
          "R_H = S_H/(S_H+S_E) above this selects the homography");
  v.field("min_parallax_deg", min_parallax_deg, 0.0, 45.0, "parallax gate (degrees)");
  v.field("min_parallax_px", min_parallax_px, 0.0, 200.0,
          "parallax gate in pixels of the focal length (parallax_px / fx radians; 0: off); the "
          "larger of this and min_parallax_deg applies");
  v.field("parallax_quantile", parallax_quantile, 0.0, 1.0,
          "quantile of triangulation angles that must pass the parallax gate");
  v.field("min_inlier_fraction", min_inlier_fraction, 0.0, 1.0,
          "matches that must agree with the rigid motion (rejects moving objects)");
  v.field("min_points", min_points, 10, 10000, "triangulated points needed");
  v.field("max_reference_age", max_reference_age, 2, 100000,
          "frames before the reference is renewed");
  v.field("ransac_max_iterations", ransac_max_iterations, 10, 100000,
          "RANSAC iterations at most for the essential matrix and the homography (bounds the "
          "cost of an attempt)");
  v.field("ransac_screen_iterations", ransac_screen_iterations, 0, 100000,
          "essential-matrix samples of the screening fit: fewer than min_inlier_fraction/2 of "
          "the matches agree -> attempt refused early (0: off)");
  v.field("low_flow_floor_frac", low_flow_floor_frac, 0.0, 1.0,
          "below the motion gate but above this median flow (fraction of image width), a pair "
          "is still tried and needs low_flow_parallax_deg");
  v.field("low_flow_parallax_deg", low_flow_parallax_deg, 0.0, 45.0,
          "parallax gate (degrees) of a pair below the motion gate (0: such pairs are refused)");
  v.field("rotation_bins", rotation_bins, 0, 360,
          "an inconsistent pair at large flow is tried again with the matches in the fullest "
          "bins of this histogram of keypoint angle changes (0: off)");
  v.field("rotation_keep_bins", rotation_keep_bins, 1, 360,
          "fullest bins of the angle-change histogram whose matches are kept");
  v.field("rotation_min_flow_frac", rotation_min_flow_frac, 0.0, 1.0,
          "median flow (fraction of image width) from which an inconsistent pair is tried again "
          "with the rotation-consistent matches");
  v.field("fast_flow_frac", fast_flow_frac, 0.0, 1.0,
          "median flow (fraction of image width) from which a pair is fast motion: the tracker "
          "switches to fast_motion_levels and starts initializing again (0: never)");
}

Initializer::Initializer(const InitializerParams& params, const FeatureParams& features,
                         const PinholeIntrinsics& K, const BundleAdjustmentParams& ba)
    : params_(params), fparams_(features), K_(K), ba_(ba) {}

void Initializer::reset() {
  has_ref_ = false;
  ref_age_ = 0;
}

int Initializer::match(const Features& cur) {
  const int nref = ref_.count;
  match_of_ref_.assign(nref, -1);
  claims_.reset(nref, cur.count);
  cand_.resize(4096);
  const float radius = static_cast<float>(params_.search_radius_frac * cur.width);
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kInit, bin);
  for (int i = 0; i < nref; ++i) {
    const int n =
        cur.radius_search(ref_.un[i].x, ref_.un[i].y, radius, ref_.level[i] - 1, ref_.level[i] + 1,
                          cand_.data(), static_cast<int>(cand_.size()));
    const BestTwo best = best_of(ref_.desc_ptr(i), cur, cand_.data(), n, bin);
    if (rule.accepts(best)) claims_.offer(i, best.index, best.d1);
  }
  for (int i = 0; i < nref; ++i) match_of_ref_[i] = claims_.target_of(i);
  return claims_.matched();
}

namespace {

double score_homography(const Eigen::Matrix3d& H, const std::vector<cv::Point2f>& x0,
                        const std::vector<cv::Point2f>& x1) {
  const Eigen::Matrix3d Hi = H.inverse();
  constexpr double kTh = 5.991, kGamma = 5.991;
  double s = 0;
  for (size_t i = 0; i < x0.size(); ++i) {
    const Eigen::Vector3d a(x0[i].x, x0[i].y, 1), b(x1[i].x, x1[i].y, 1);
    const Eigen::Vector3d ha = H * a, hb = Hi * b;
    const double e1 = (ha.head<2>() / ha.z() - b.head<2>()).squaredNorm();
    const double e2 = (hb.head<2>() / hb.z() - a.head<2>()).squaredNorm();
    if (e1 < kTh) s += kGamma - e1;
    if (e2 < kTh) s += kGamma - e2;
  }
  return s;
}

double score_essential(const Eigen::Matrix3d& F, const std::vector<cv::Point2f>& x0,
                       const std::vector<cv::Point2f>& x1) {
  constexpr double kTh = 3.841, kGamma = 5.991;
  double s = 0;
  const Eigen::Matrix3d Ft = F.transpose();
  for (size_t i = 0; i < x0.size(); ++i) {
    const Eigen::Vector2d a(x0[i].x, x0[i].y), b(x1[i].x, x1[i].y);
    const double e1 = epipolar_dist2(F, a, b);
    const double e2 = epipolar_dist2(Ft, b, a);
    if (e1 < kTh) s += kGamma - e1;
    if (e2 < kTh) s += kGamma - e2;
  }
  return s;
}

struct Hypothesis {
  Pose T;
  int good = 0;
  std::vector<double> parallax_deg;
  std::vector<int> idx;  // match indices triangulated with enough parallax
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> pts;
};

void check_motion(const PinholeIntrinsics& K, const std::vector<cv::Point2f>& x0,
                  const std::vector<cv::Point2f>& x1, Hypothesis& h) {
  const Pose T0;
  const Eigen::Vector3d c0 = T0.centre(), c1 = h.T.centre();
  constexpr double kMinCos = 0.99998;   // ~0.36 deg: below this depth sign is unreliable
  constexpr double kPointCos = 0.9998;  // ~1.15 deg: map points need this parallax
  constexpr double kReproj2 = 4.0;      // (2 px)^2
  for (size_t i = 0; i < x0.size(); ++i) {
    const Eigen::Vector3d b0 = K.unproject(x0[i].x, x0[i].y);
    const Eigen::Vector3d b1 = K.unproject(x1[i].x, x1[i].y);
    Eigen::Vector3d p;
    if (!triangulate_dlt(T0, b0, h.T, b1, p)) continue;
    const double cosp = parallax_cos(p, c0, c1);
    const Eigen::Vector3d q = h.T * p;
    if ((p.z() <= 0 || q.z() <= 0) && cosp < kMinCos) continue;
    if (p.z() <= 0 || q.z() <= 0) continue;
    const double e0 = (K.project(p) - Eigen::Vector2d(x0[i].x, x0[i].y)).squaredNorm();
    const double e1 = (K.project(q) - Eigen::Vector2d(x1[i].x, x1[i].y)).squaredNorm();
    if (e0 > kReproj2 || e1 > kReproj2) continue;
    ++h.good;
    h.parallax_deg.push_back(std::acos(std::min(1.0, cosp)) * 180.0 / M_PI);
    if (cosp < kPointCos) {
      h.idx.push_back(static_cast<int>(i));
      h.pts.push_back(p);
    }
  }
}

// The samples OpenCV's RANSAC draws once its best model has `inliers` of `n` points in its
// consensus (RANSACUpdateNumIters, opencv/modules/calib3d/src/ptsetreg.cpp), at most `cap`.
int ransac_samples_needed(double prob, int inliers, int n, int model_points, int cap) {
  const double ep = std::clamp(static_cast<double>(n - inliers) / n, 0.0, 1.0);
  const double num = std::log(std::max(1.0 - prob, std::numeric_limits<double>::min()));
  const double q = 1.0 - std::pow(1.0 - ep, model_points);
  if (q < std::numeric_limits<double>::min()) return 0;
  const double denom = std::log(q);
  if (denom >= 0 || -num >= cap * (-denom)) return cap;
  return static_cast<int>(std::lround(num / denom));
}

Pose from_cv(const cv::Mat& R, const cv::Mat& t) {
  Pose T;
  cv::cv2eigen(R, T.R);
  Eigen::Vector3d tt;
  cv::cv2eigen(t, tt);
  T.t = tt;
  return T;
}

}  // namespace

InitStatus Initializer::add_frame(const Features& cur, int64_t stamp_ns, InitResult& out) {
  if (cur.count < params_.min_features) return InitStatus::kNoReference;
  if (!has_ref_ || ref_age_ >= params_.max_reference_age) {
    ref_.copy_from(cur);
    has_ref_ = true;
    ref_age_ = 0;
    ref_stamp_ = stamp_ns;
    return InitStatus::kNoReference;
  }
  ++ref_age_;
  return attempt(cur, stamp_ns, out);
}

InitStatus Initializer::retry_with_reference(const Features& ref, const Features& cur,
                                             int64_t stamp_ns, InitResult& out) {
  if (!has_ref_ || cur.count < params_.min_features) return add_frame(cur, stamp_ns, out);
  ref_.copy_from(ref);  // the same frame (stamp, age), described again
  return attempt(cur, stamp_ns, out);
}

InitStatus Initializer::attempt(const Features& cur, int64_t stamp_ns, InitResult& out) {
  attempt_ = InitAttempt{};
  const InitStatus s = evaluate(cur, out);
  const InitAttempt& a = attempt_;
  RDSLAM_LOG_DEBUG(
      "initializer: age %d matches %d flow %.1f px%s E inliers %d model %s R_H %.2f consistent %d "
      "(2nd %d) parallax %.2f deg points %d%s: %s",
      ref_age_, a.matches, a.median_flow_px, a.low_flow ? " (low)" : "", a.e_inliers,
      a.homography ? "H" : "E", a.r_h, a.consistent, a.second, a.parallax_deg, a.points,
      a.rotation_removed > 0 ? " (rotation check)" : "", to_string(s));
  if (s == InitStatus::kFewMatches) {
    // The view changed too much (or the reference was poor): start again from this frame.
    ref_.copy_from(cur);
    ref_age_ = 0;
    ref_stamp_ = stamp_ns;
  }
  return s;
}

int Initializer::filter_by_rotation(const Features& cur) {
  // ORB-SLAM's rotation consistency (Mur-Artal et al. 2015, Sec. IV-A; ORBmatcher's
  // SearchForInitialization): a histogram of the keypoint angle changes of the matches, and only
  // the matches in its `rotation_keep_bins` fullest bins are kept. A rigid scene under a camera
  // motion without large roll turns every keypoint by about the same angle; a wrong match has a
  // random angle change.
  const int bins = params_.rotation_bins;
  rot_hist_.assign(bins, 0);
  const float to_bin = static_cast<float>(bins) / 360.f;
  auto bin_of = [&](int i, int j) {
    float d = ref_.kps[i].angle - cur.kps[j].angle;
    if (d < 0.f) d += 360.f;
    return std::min(bins - 1, std::max(0, static_cast<int>(std::lround(d * to_bin)) % bins));
  };
  for (int i = 0; i < ref_.count; ++i) {
    if (match_of_ref_[i] >= 0) ++rot_hist_[bin_of(i, match_of_ref_[i])];
  }
  // The fullest bins; a bin far below the fullest (< 10% of it) is not kept.
  std::vector<int> order(bins);
  for (int b = 0; b < bins; ++b) order[b] = b;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return rot_hist_[a] > rot_hist_[b]; });
  rot_keep_.assign(bins, 0);
  const int top = rot_hist_[order[0]];
  for (int k = 0; k < std::min(bins, params_.rotation_keep_bins); ++k) {
    if (rot_hist_[order[k]] >= 0.1 * top) rot_keep_[order[k]] = 1;
  }
  int kept = 0;
  for (int i = 0; i < ref_.count; ++i) {
    const int j = match_of_ref_[i];
    if (j < 0) continue;
    if (rot_keep_[bin_of(i, j)]) {
      ++kept;
    } else {
      match_of_ref_[i] = -1;
    }
  }
  return kept;
}

InitStatus Initializer::evaluate(const Features& cur, InitResult& out) {
  const int nm = match(cur);
  attempt_.matches = nm;
  if (nm < params_.min_matches) return InitStatus::kFewMatches;
  const InitStatus s = evaluate_matches(cur, out, nm);
  if (s != InitStatus::kInconsistent || params_.rotation_bins <= 0 ||
      attempt_.median_flow_px < params_.rotation_min_flow_frac * cur.width) {
    return s;
  }
  // Too few matches agree with the motion at a large image flow (kitti06 `--every 3`: about
  // 40% of the first pair's matches are wrong): the attempt is repeated once with the matches
  // whose keypoint orientation changed like most others'.
  const int kept = filter_by_rotation(cur);
  if (kept == nm || kept < params_.min_matches) return s;
  attempt_ = InitAttempt{};
  attempt_.matches = kept;
  attempt_.rotation_removed = nm - kept;
  return evaluate_matches(cur, out, kept);
}

InitStatus Initializer::evaluate_matches(const Features& cur, InitResult& out, int nm) {
  std::vector<cv::Point2f> x0, x1;
  std::vector<int> f0, f1;
  std::vector<double> flow;
  for (int i = 0; i < ref_.count; ++i) {
    const int j = match_of_ref_[i];
    if (j < 0) continue;
    x0.push_back(ref_.un[i]);
    x1.push_back(cur.un[j]);
    f0.push_back(i);
    f1.push_back(j);
    flow.push_back(std::hypot(ref_.un[i].x - cur.un[j].x, ref_.un[i].y - cur.un[j].y));
  }
  std::nth_element(flow.begin(), flow.begin() + flow.size() / 2, flow.end());
  // Motion gate: most of the scene must move in the image (camera motion, not noise or a few
  // moving objects). Below it, down to its floor, the pair must show a larger parallax.
  const double med_flow = flow[flow.size() / 2];
  attempt_.median_flow_px = med_flow;
  if (fast_check_ && params_.fast_flow_frac > 0.0 &&
      med_flow >= params_.fast_flow_frac * cur.width) {
    return InitStatus::kFastMotion;
  }
  if (med_flow < params_.min_median_flow_frac * cur.width) {
    if (params_.low_flow_parallax_deg <= 0.0 ||
        med_flow < params_.low_flow_floor_frac * cur.width) {
      return InitStatus::kLittleMotion;
    }
    attempt_.low_flow = true;
  }
  const cv::Matx33d Kcv(K_.fx, 0, K_.cx, 0, K_.fy, K_.cy, 0, 0, 1);
  cv::theRNG().state = 12345;  // deterministic RANSAC
  cv::Mat maskE, maskH;
  // Low-flow pairs: USAC_ACCURATE, RANSAC with local optimisation (the best sample's model is
  // refit on its inliers). Plain RANSAC keeps the best five-point model as it is: at these
  // small baselines its translation direction, and the parallax measured with it, jump from
  // frame to frame (sitting: median 1.51, 1.54, 1.07, 1.61 deg at ages 6-9), so the parallax
  // gate passed or failed by chance. Above the motion gate plain RANSAC is kept: it was
  // adequate there, and USAC moved kitti06's start from frame 1 (median parallax 0.98 deg
  // against the 1 deg gate) to frame 2.
  const int method = attempt_.low_flow ? cv::USAC_ACCURATE : cv::RANSAC;
  constexpr double kProb = 0.999, kThresholdPx = 1.0;
  const int screen = params_.ransac_screen_iterations;
  cv::Mat E;
  bool fitted = false;
  if (method == cv::RANSAC && screen > 0 && screen < params_.ransac_max_iterations) {
    // Screening fit: the first `screen` samples of the full fit (same seed, same order).
    E = cv::findEssentialMat(x0, x1, Kcv, method, kProb, kThresholdPx, screen, maskE);
    const bool ok = !E.empty() && E.rows == 3 && E.cols == 3;
    const int inl = ok ? cv::countNonZero(maskE) : 0;
    if (inl < 0.5 * params_.min_inlier_fraction * static_cast<double>(nm)) {
      attempt_.e_inliers = inl;
      return InitStatus::kInconsistent;
    }
    // OpenCV's RANSAC stops after the samples that its best consensus calls for; when that
    // is below the screen's cap, the full fit would have stopped at the same sample.
    fitted =
        ok && ransac_samples_needed(kProb, inl, nm, 5, params_.ransac_max_iterations) < screen - 1;
    if (!fitted) cv::theRNG().state = 12345;
  }
  if (!fitted) {
    E = cv::findEssentialMat(x0, x1, Kcv, method, kProb, kThresholdPx,
                             params_.ransac_max_iterations, maskE);
  }
  cv::Mat H =
      cv::findHomography(x0, x1, cv::RANSAC, 2.0, maskH, params_.ransac_max_iterations, 0.999);
  if (E.empty() || E.rows != 3 || E.cols != 3 || H.empty()) return InitStatus::kModelFailed;
  attempt_.e_inliers = cv::countNonZero(maskE);
  Eigen::Matrix3d Ee, He;
  cv::cv2eigen(E, Ee);
  cv::cv2eigen(H, He);
  Eigen::Matrix3d Kinv;
  Kinv << 1.0 / K_.fx, 0, -K_.cx / K_.fx, 0, 1.0 / K_.fy, -K_.cy / K_.fy, 0, 0, 1;
  const Eigen::Matrix3d F = Kinv.transpose() * Ee * Kinv;
  const double sH = score_homography(He, x0, x1);
  const double sE = score_essential(F, x0, x1);
  const bool use_h = sH + sE > 0 && sH / (sH + sE) > params_.homography_ratio;
  attempt_.homography = use_h;
  attempt_.r_h = sH + sE > 0 ? sH / (sH + sE) : 0.0;

  std::vector<Hypothesis> hyps;
  if (use_h) {
    std::vector<cv::Mat> Rs, ts, ns;
    cv::decomposeHomographyMat(H, Kcv, Rs, ts, ns);
    for (size_t k = 0; k < Rs.size(); ++k) {
      Hypothesis h;
      h.T = from_cv(Rs[k], ts[k]);
      hyps.push_back(std::move(h));
    }
  } else {
    cv::Mat R1, R2, t;
    cv::decomposeEssentialMat(E, R1, R2, t);
    for (const cv::Mat* R : {&R1, &R2}) {
      for (double sgn : {1.0, -1.0}) {
        Hypothesis h;
        h.T = from_cv(*R, t * sgn);
        hyps.push_back(std::move(h));
      }
    }
  }
  for (auto& h : hyps) {
    if (h.T.t.norm() < 1e-12) continue;
    h.T.t.normalize();
    check_motion(K_, x0, x1, h);
  }
  std::sort(hyps.begin(), hyps.end(),
            [](const Hypothesis& a, const Hypothesis& b) { return a.good > b.good; });
  if (hyps.empty() || hyps[0].good == 0) return InitStatus::kModelFailed;
  attempt_.consistent = hyps[0].good;
  attempt_.second = hyps.size() > 1 ? hyps[1].good : 0;
  attempt_.points = static_cast<int>(hyps[0].idx.size());
  // The best hypothesis must be clearly better than any other.
  if (hyps.size() > 1 && hyps[1].good > 0.75 * hyps[0].good) return InitStatus::kAmbiguous;
  Hypothesis& best = hyps[0];
  if (best.good < params_.min_inlier_fraction * static_cast<double>(x0.size())) {
    return InitStatus::kInconsistent;
  }
  std::vector<double> par = best.parallax_deg;
  std::sort(par.begin(), par.end());
  const size_t qi =
      std::min(par.size() - 1, static_cast<size_t>(params_.parallax_quantile * (par.size() - 1)));
  attempt_.parallax_deg = par[qi];
  const double gate_deg =
      std::max(params_.min_parallax_deg, params_.min_parallax_px / K_.fx * 180.0 / M_PI);
  const double min_parallax =
      attempt_.low_flow ? std::max(gate_deg, params_.low_flow_parallax_deg) : gate_deg;
  if (par[qi] < min_parallax) return InitStatus::kLowParallax;
  if (static_cast<int>(best.idx.size()) < params_.min_points) return InitStatus::kFewPoints;

  // Two-view bundle adjustment in a scratch map (reference keyframe fixed).
  Map m;
  Keyframe& k0 = m.keyframes[0];
  k0.id = 0;
  k0.fixed = true;
  k0.features.copy_from(ref_);
  k0.point_of.assign(ref_.count, -1);
  Keyframe& k1 = m.keyframes[1];
  k1.id = 1;
  k1.T_cam_world = best.T;
  k1.features.copy_from(cur);
  k1.point_of.assign(cur.count, -1);
  for (size_t k = 0; k < best.idx.size(); ++k) {
    MapPoint p;
    p.id = static_cast<int64_t>(k);
    p.p_world = best.pts[k];
    m.points.emplace(p.id, p);
    m.add_observation(p.id, 0, f0[best.idx[k]]);
    m.add_observation(p.id, 1, f1[best.idx[k]]);
  }
  BundleAdjustmentParams ba = ba_;
  ba.iterations = 20;
  bundle_adjust(m, K_, {0, 1}, ba);
  if (static_cast<int>(m.points.size()) < params_.min_points) return InitStatus::kFewPoints;
  // Scale: median depth in the reference camera = 1.
  std::vector<double> depth;
  for (const auto& kv : m.points) depth.push_back(kv.second.p_world.z());
  std::nth_element(depth.begin(), depth.begin() + depth.size() / 2, depth.end());
  const double med = depth[depth.size() / 2];
  if (!(med > 1e-9)) return InitStatus::kFewPoints;
  const double s = 1.0 / med;
  out.T1 = m.keyframes[1].T_cam_world;
  out.T1.t *= s;
  out.points.clear();
  for (const auto& kv : m.points) {
    InitPoint ip;
    ip.p_world = kv.second.p_world * s;
    for (const auto& o : kv.second.obs) {
      if (o.kf == 0) ip.feat0 = o.feat;
      if (o.kf == 1) ip.feat1 = o.feat;
    }
    if (ip.feat0 >= 0 && ip.feat1 >= 0) out.points.push_back(ip);
  }
  out.homography = use_h;
  out.median_parallax_deg = par[par.size() / 2];
  out.reference = &ref_;
  out.reference_stamp_ns = ref_stamp_;
  return InitStatus::kOk;
}

}  // namespace rdslam
