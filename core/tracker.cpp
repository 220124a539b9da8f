#include "core/tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/log.h"
#include "core/matching.h"
#include "core/pose_refine.h"
#include "core/prefix_visitor.h"
#include "core/relocalizer.h"

namespace rdslam {

void TrackerParams::visit(ParamVisitor& v) {
  v.field("min_inliers", min_inliers, 6, 10000, "inliers needed to publish TRACKING");
  v.field("reloc_min_inliers", reloc_min_inliers, 6, 10000, "inliers needed to relocalize");
  v.field("motion_search_px", motion_search_px, 1.0, 500.0,
          "motion-model search radius (pixels at level 0)");
  v.field("local_search_px", local_search_px, 0.5, 100.0, "map-point projection search radius");
  v.field("search_min_matches", search_min_matches, 6, 10000,
          "matches a projection search needs before a pose is estimated from them");
  v.field("search_min_inliers", search_min_inliers, 6, 10000,
          "fewer inliers from a search: try the next one (wider motion search, then local map)");
  v.field("extend_min_inliers", extend_min_inliers, 6, 10000,
          "inliers needed to extend the pose with the local map (else LOST)");
  v.field("robust_min_inliers", robust_min_inliers, 6, 10000,
          "a robust estimate (parsac.method) with fewer inliers is no model");
  v.field("reloc_min_matches", reloc_min_matches, 6, 10000,
          "global matches needed to attempt a relocalization");
  v.field("reloc_candidates", reloc_candidates, 1, 20,
          "place recognition: keyframes whose points a LOST frame is matched with (ORB)");
  v.field("reloc_node_level", reloc_node_level, 1, 8,
          "place recognition: vocabulary level of the direct index (features matched per node)");
  v.field("reloc_vocabulary", reloc_vocabulary, {},
          "ORB vocabulary file (empty: the built-in data/vocab/orb_k10l4.bin)");
  v.field("m1", m1, 1, 100000, "paper Sec. 4: fewer common features -> potential keyframe");
  v.field("keyframe_overlap_ratio", keyframe_overlap_ratio, 0.0, 1.0,
          "or tracked points below this fraction of the reference keyframe's");
  v.field("max_keyframe_interval", max_keyframe_interval, 1, 100000,
          "frames after which a keyframe is proposed anyway");
  v.field("young_map_keyframes", young_map_keyframes, 0, 100000,
          "a map with fewer keyframes than this is young (0: never)");
  v.field("young_map_keyframe_interval", young_map_keyframe_interval, 1, 100000,
          "max_keyframe_interval while the map is young");
  v.field("reset_after_lost_frames", reset_after_lost_frames, 1, 100000,
          "lost this long with <= 2 keyframes: re-initialize");
  v.field("new_map_after_s", new_map_after_s, 0.0, 3600.0,
          "recovery: lost this long (s) with any map: start a new map epoch, keeping the old map "
          "for relocalization and merging (0: never)");
  v.field("prediction_max_scale", prediction_max_scale, 1.0, 100.0,
          "the motion prediction spans at most this many (at least 1/this) of the last motion's "
          "stamp intervals (frames dropped between tracked frames)");
  v.field("robust_per_frame", robust_per_frame,
          "robust pose (parsac.method) on every frame before the eq. (1) refinement");
  v.field("submotion_chi2", submotion_chi2, 0.0, 1000.0,
          "sub-motion test: drop bins whose mean residual exceeds this chi-square (2 DoF; 0 off)");
  v.field("submotion_gate_px", submotion_gate_px, 0.1, 100.0,
          "sub-motion test: inlier gate of its second robust estimate (pixels)");
  v.field("rotation_only", rotation_only,
          "rotation-only tracking while the camera turns on the spot out of its map");
  v.field("rotation_min_deg", rotation_min_deg, 0.0, 90.0,
          "rotation mode: the last motion turned at least this much per frame (degrees)");
  v.field("rotation_max_parallax_ratio", rotation_max_parallax_ratio, 0.0, 10.0,
          "rotation mode: the last translation / median depth is below this x its angle");
  v.field("rotation_refresh_ratio", rotation_refresh_ratio, 0.0, 1.0,
          "next rotation-only keyframe when its bearing matches fall below this fraction");
  v.field("rotation_exit_max_shift", rotation_exit_max_shift, 0.0, 10.0,
          "rotation mode ends with a full pose within this x its median depth of the centre");
  v.field("fast_motion_levels", fast_motion_levels, 0, 8,
          "ORB pyramid levels once an initialization attempt sees fast motion "
          "(init_fast_flow_frac; 0 or <= features.levels: off)");
  v.field("fast_motion_features", fast_motion_features, 0, 10000,
          "features per frame on the fast-motion pyramid (0: features.max_features)");
  v.field("sync_mapper", sync_mapper,
          "wait for the mapper after each keyframe (lossless replay only; never for cameras)");
  PrefixVisitor init_v(v, "init_");
  init.visit(init_v);
}

namespace {

// Scale of the last motion for a frame `dt_ns` after the last tracked frame, when that motion
// spanned `motion_dt_ns`: their ratio, clamped to [1 / max_scale, max_scale]. 1 when either
// interval is not positive (stamps not increasing: one motion per frame, as without stamps)
// and when the ratio is within 1% of 1 (stamp rounding and jitter of a steady frame rate, so
// a sequence without drops predicts exactly as one motion per frame).
double motion_scale(int64_t dt_ns, int64_t motion_dt_ns, double max_scale) {
  if (dt_ns <= 0 || motion_dt_ns <= 0) return 1.0;
  const double r = static_cast<double>(dt_ns) / static_cast<double>(motion_dt_ns);
  if (std::abs(r - 1.0) < 0.01) return 1.0;
  return std::clamp(r, 1.0 / max_scale, max_scale);
}

// `motion` continued for `s` times its duration: rotation angle and translation scaled by s
// (as the initial velocity is spread over the initialization's frames).
Pose scale_motion(const Pose& motion, double s) {
  const Eigen::AngleAxisd aa(motion.R);
  return Pose{Eigen::AngleAxisd(aa.angle() * s, aa.axis()).toRotationMatrix(), motion.t * s};
}

// Whether the run may switch to the fast-motion pyramid (TrackerParams::fast_motion_levels).
bool fast_motion_enabled(const TrackerParams& params, const FeatureParams& features) {
  return features.binary() && params.fast_motion_levels > features.levels;
}

// The features a frame can carry: features.max_features, or the fast-motion budget when the
// run may switch to it and it is larger. The per-frame buffers are sized for it at start.
FeatureParams with_frame_capacity(const TrackerParams& params, const FeatureParams& features) {
  FeatureParams f = features;
  if (fast_motion_enabled(params, features)) {
    f.max_features = std::max(f.max_features, params.fast_motion_features);
  }
  return f;
}

}  // namespace

void Tracker::FrameState::reset_matches(int n) {
  std::fill(pid.begin(), pid.begin() + n, int64_t{-1});
  std::fill(row.begin(), row.begin() + n, -1);
  std::fill(best_dist.begin(), best_dist.begin() + n, 1e30f);
}

Tracker::Tracker(const TrackerParams& params, const FeatureParams& features,
                 const BundleAdjustmentParams& ba, const ParsacParams& parsac,
                 const CameraModel& camera, std::shared_ptr<SlamLink> link, int max_points,
                 int max_keyframes)
    : params_(params),
      fparams_(with_frame_capacity(params, features)),
      camera_(camera),
      K_{camera.fx, camera.fy, camera.cx, camera.cy},
      link_(std::move(link)),
      extractor_(features, camera),
      initializer_(params.init, features, K_, ba),
      estimator_(parsac, camera, fparams_.max_features + 64),
      tight_(
          [&] {
            ParsacParams q = parsac;
            q.inlier_threshold_px = params.submotion_gate_px;
            return q;
          }(),
          camera, fparams_.max_features + 64),
      reloc_(RelocalizerParams{params.reloc_candidates, params.reloc_node_level}, fparams_,
             link_->vocabulary, max_keyframes, max_points) {
  const size_t cap = static_cast<size_t>(fparams_.max_features) + 64;
  for (FrameState* s : {&cur_, &last_}) {
    s->pid.assign(cap, -1);
    s->p.assign(cap, Eigen::Vector3d::Zero());
    s->row.assign(cap, -1);
    s->best_dist.assign(cap, 1e30f);
  }
  cand_.resize(2048);
  corr_p_.resize(cap);
  corr_x_.resize(cap);
  corr_s_.resize(cap);
  corr_feat_.resize(cap);
  corr_inl_.resize(cap);
  reloc_pairs_.resize(2 * cap);
  bins_x_ = parsac.bins_x;
  bins_y_ = parsac.bins_y;
  bin_sum_.assign(static_cast<size_t>(bins_x_ * bins_y_), Eigen::Vector2d::Zero());
  bin_count_.assign(bin_sum_.size(), 0);
  bin_flag_.assign(bin_sum_.size(), 0);
  corr_bin_.assign(cap, 0);
  row_stamp_.assign(static_cast<size_t>(max_points) + 4096, -1);
  row_rejected_.assign(row_stamp_.size(), -1);
  kf_votes_.reserve(4096);
  levels_ = std::max(1, features.levels);
  if (fast_motion_enabled(params, features)) {
    FeatureParams fast = features;
    fast.levels = params.fast_motion_levels;
    if (params.fast_motion_features > 0) fast.max_features = params.fast_motion_features;
    fast_extractor_ = std::make_unique<FeatureExtractor>(fast, camera);
    initializer_.set_fast_motion_check(true);
  }
  level_scale_.resize(std::max(levels_, fast_extractor_ ? params.fast_motion_levels : 0));
  for (size_t l = 0; l < level_scale_.size(); ++l) {
    level_scale_[l] = static_cast<float>(std::pow(features.scale_factor, double(l)));
  }
  // Rotation-only tracking: the rotation keyframe's buffers at the feature cap.
  rot_kf_.kps.resize(cap);
  rot_kf_.un.resize(cap);
  rot_kf_.scale.resize(cap);
  rot_kf_.level.resize(cap);
  rot_kf_.desc.create(static_cast<int>(cap), features.is_sift() ? 128 : 32,
                      features.is_sift() ? CV_32F : CV_8U);
  rot_kf_.cell_items.resize(cap);  // its grid (copy_from builds it): cells of >= 8 px
  const cv::Rect2d extent = camera.ideal_extent();  // the grid's rectangle (a lens widens it)
  rot_kf_.cell_start.reserve(static_cast<size_t>((extent.width / 8 + 2) * (extent.height / 8 + 2)) +
                             1);
  rot_bearing_.assign(cap, Eigen::Vector3d::Zero());
  bear_of_.assign(cap, -1);
  bear_dist_.assign(cap, 1e30f);
  corr_bear_.assign(cap, -1);
  depth_scratch_.resize(cap);
  // Warm up the frame buffers so the first frames do not allocate inside track().
  gray_.create(camera.height, camera.width, CV_8UC1);
}

void Tracker::refresh_snapshot() {
  const uint64_t v = link_->index.version();
  if (v == snap_version_) return;
  snap_version_ = v;
  std::shared_ptr<const MapSnapshot> s = link_->index.acquire();
  if (!s) return;
  if (s->epoch != epoch_) {
    if (s->merged_from < 0 || static_cast<uint32_t>(s->merged_from) != epoch_) return;
    follow_merge(*s);  // this map was merged into an earlier one: continue in its frame
  }
  snap_ = std::move(s);  // the previous snapshot is freed by the mapper (MatchIndex::collect)
  if (static_cast<int>(row_stamp_.size()) < snap_->rows()) {
    row_stamp_.resize(static_cast<size_t>(snap_->rows()) * 2, -1);  // map above its cap
    row_rejected_.resize(row_stamp_.size(), -1);
  }
  // Bundle adjustment moved points: refresh the previous frame's positions and rows.
  for (int i = 0; i < last_.f.count; ++i) {
    if (last_.pid[i] < 0) continue;
    const int r = snap_->find(last_.pid[i]);
    last_.row[i] = r;
    if (r >= 0) last_.p[i] = snap_->p_world[r];
  }
}

void Tracker::follow_merge(const MapSnapshot& s) {
  // x' = c R x + t (core/map_merge.h Sim3): a camera pose T becomes (T.R R^T, c T.t - T.R R^T t),
  // the motion between two frames keeps its rotation and scales its translation by c.
  const double c = s.merge_scale;
  auto move_pose = [&](Pose& T) {
    const Eigen::Matrix3d Rn = T.R * s.merge_R.transpose();
    T.t = c * T.t - Rn * s.merge_t;
    T.R = Rn;
  };
  move_pose(last_.T);
  for (int i = 0; i < last_.f.count; ++i) {
    if (last_.pid[i] < 0) continue;
    last_.pid[i] += s.merge_point_offset;
    last_.p[i] = c * (s.merge_R * last_.p[i]) + s.merge_t;
  }
  velocity_.t *= c;
  RDSLAM_LOG_INFO("tracker: map epoch %u merged into epoch %u: continuing in its frame", epoch_,
                  s.epoch);
  epoch_ = s.epoch;
}

int Tracker::match_motion(const Pose& T, double radius) {
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kMotion, bin);
  for (int i = 0; i < last_.f.count; ++i) {
    if (last_.pid[i] < 0) continue;
    const Eigen::Vector3d pc = T * last_.p[i];
    if (pc.z() <= 1e-6) continue;
    const Eigen::Vector2d uv = K_.project(pc);
    if (!camera_.ideal_in_image(uv)) continue;
    const int lvl = last_.f.level[i];
    const int n = cur_.f.radius_search(
        float(uv.x()), float(uv.y()), float(radius * last_.f.scale[i]), bin ? lvl - 1 : -1,
        bin ? lvl + 1 : 1 << 20, cand_.data(), static_cast<int>(cand_.size()));
    const BestTwo best = best_of(last_.f.desc_ptr(i), cur_.f, cand_.data(), n, bin);
    if (!rule.accepts(best)) continue;
    const int bj = best.index;
    const double b1 = best.d1;
    if (b1 >= cur_.best_dist[bj]) continue;
    cur_.pid[bj] = last_.pid[i];
    cur_.p[bj] = last_.p[i];
    cur_.row[bj] = last_.row[i];
    cur_.best_dist[bj] = static_cast<float>(b1);
  }
  int m = 0;
  for (int j = 0; j < cur_.f.count; ++j) m += cur_.pid[j] >= 0;
  return m;
}

int Tracker::match_local_map(const Pose& T, double radius) {
  if (!snap_) return 0;
  const MapSnapshot& s = *snap_;
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kLocalMap, bin);
  const Eigen::Vector3d c = T.centre();
  const double log_sf = std::log(std::max(1.0001, fparams_.scale_factor));
  const int L = levels_;
  for (int j = 0; j < cur_.f.count; ++j) {
    if (cur_.row[j] >= 0) row_stamp_[cur_.row[j]] = frame_no_;
  }
  int added = 0;
  for (int r = 0; r < s.rows(); ++r) {
    if (row_stamp_[r] == frame_no_ || row_rejected_[r] == track_no_) continue;
    const Eigen::Vector3d& p = s.p_world[r];
    const Eigen::Vector3d pc = T * p;
    if (pc.z() <= 1e-6) continue;
    const Eigen::Vector2d uv = K_.project(pc);
    if (!camera_.ideal_in_image(uv)) continue;
    const Eigen::Vector3d v = c - p;
    const double dist = v.norm();
    if (bin && (dist < s.min_dist[r] || dist > s.max_dist[r])) continue;
    const double view_cos = s.normal[r].cast<double>().dot(v) / std::max(1e-12, dist);
    if (view_cos < 0.5) continue;
    int lvl = 0, lo = -1, hi = 1 << 20;
    if (bin) {
      lvl = predict_level(s.max_dist[r], dist, log_sf, L);
      lo = lvl - 1;
      hi = lvl + 1;
    }
    const double rad = radius * (view_cos > 0.998 ? 1.0 : 1.5) * level_scale_[lvl];
    const int n = cur_.f.radius_search(float(uv.x()), float(uv.y()), float(rad), lo, hi,
                                       cand_.data(), static_cast<int>(cand_.size()));
    const BestTwo best = best_of(s.desc.ptr<uint8_t>(r), cur_.f, cand_.data(), n, bin,
                                 [this](int j) { return cur_.pid[j] >= 0; });
    if (!rule.accepts(best)) continue;
    const int bj = best.index;
    const double b1 = best.d1;
    cur_.pid[bj] = s.ids[r];
    cur_.p[bj] = p;
    cur_.row[bj] = r;
    cur_.best_dist[bj] = static_cast<float>(b1);
    row_stamp_[r] = frame_no_;
    ++added;
  }
  return added;
}

void Tracker::set_correspondence(int k, int j, const Eigen::Vector3d& p) {
  corr_p_[k] = p;
  corr_x_[k] = Eigen::Vector2d(cur_.f.un[j].x, cur_.f.un[j].y);
  corr_s_[k] = cur_.f.scale[j];
  corr_feat_[k] = j;
}

int Tracker::pack_matches() {
  int n = 0;
  for (int j = 0; j < cur_.f.count; ++j) {
    if (cur_.pid[j] < 0) continue;
    set_correspondence(n++, j, cur_.p[j]);
  }
  return n;
}

int Tracker::optimise(Pose& T) {
  const int n = pack_matches();
  if (n < 6) return 0;
  const PoseRefineStats st =
      refine_pose(K_, corr_p_.data(), corr_x_.data(), corr_s_.data(), n, T, corr_inl_.data());
  // Outliers do not propagate to the next frame.
  for (int k = 0; k < n; ++k) {
    if (corr_inl_[k]) continue;
    const int j = corr_feat_[k];
    if (debug_sink_) debug_rejected_[j] = uint8_t(DebugFeatureKind::kRejectedRefine);
    cur_.pid[j] = -1;
    cur_.row[j] = -1;
    cur_.best_dist[j] = 1e30f;
  }
  return st.inliers;
}

void Tracker::reject_match(int j) {
  // Rejected this frame: the projection search must not match the point again, or eq. (1)
  // would re-admit what the robust estimator rejected (e.g. the moving book of Figure 8).
  if (cur_.row[j] >= 0) row_rejected_[cur_.row[j]] = track_no_;
  if (debug_sink_) debug_rejected_[j] = uint8_t(DebugFeatureKind::kRejectedRobust);
  cur_.pid[j] = -1;
  cur_.row[j] = -1;
  cur_.best_dist[j] = 1e30f;
}

int Tracker::robust_optimise(Pose& T, const Pose& guess) {
  // Sec. 3/5: PARSAC over the frame's matches, seeded with the motion-model prediction; its
  // outliers are dropped, then eq. (1) refines over the rest.
  const int n = pack_matches();
  // The prediction only guides the matching: PARSAC samples its hypotheses from the matches
  // alone (Sec. 5). Scored as an extra hypothesis, a prediction that has drifted with a slowly
  // moving object would win every frame and end the search at once (adaptive termination),
  // so every estimator would return the same drifting pose.
  Pose Tr = guess;
  const int inl = estimator_.estimate(corr_p_.data(), corr_x_.data(), corr_s_.data(), n, Tr,
                                      corr_inl_.data(), nullptr);
  if (inl < params_.robust_min_inliers) return optimise(T);  // no model: refine from the prediction
  for (int k = 0; k < n; ++k) {
    if (corr_inl_[k]) continue;
    reject_match(corr_feat_[k]);
  }
  T = Tr;
  return inl;
}

int Tracker::reject_submotion(Pose& T, int inliers, bool* dropped_any) {
  *dropped_any = false;
  // The majority rigid motion under a tight gate (see TrackerParams::submotion_chi2).
  const int m = pack_matches();
  PoseEstimate pe;
  if (tight_.estimate(corr_x_.data(), corr_p_.data(), m, nullptr, nullptr, &pe) !=
      PoseStatus::kOk) {
    return inliers;
  }
  Pose Te;
  Te.R = pe.T_cam_world.linear();
  Te.t = pe.T_cam_world.translation();
  double ss = 0.0;
  const int n = bin_residuals(Te, &ss);
  if (n < params_.min_inliers) return inliers;
  // Per-axis variance of a normalised residual, pooled over the frame's inliers.
  const double var = std::max(1e-6, ss / (2.0 * n));
  if (flag_coherent_bins(var) == 0) return inliers;
  return drop_and_refit(T, n, inliers, dropped_any);
}

int Tracker::bin_residuals(const Pose& Te, double* sum_sq) {
  // Per-bin sums of the normalised residuals under the tight pose; corr_feat_/corr_bin_ list
  // the points in front of the camera.
  std::fill(bin_sum_.begin(), bin_sum_.end(), Eigen::Vector2d::Zero());
  std::fill(bin_count_.begin(), bin_count_.end(), 0);
  std::fill(bin_flag_.begin(), bin_flag_.end(), uint8_t{0});
  int n = 0;
  double ss = 0.0;
  for (int j = 0; j < cur_.f.count; ++j) {
    if (cur_.pid[j] < 0) continue;
    const Eigen::Vector3d pc = Te * cur_.p[j];
    if (pc.z() <= 1e-6) continue;
    const Eigen::Vector2d x(cur_.f.un[j].x, cur_.f.un[j].y);
    const Eigen::Vector2d r = (K_.project(pc) - x) / double(cur_.f.scale[j]);
    int bx = static_cast<int>(x.x() * bins_x_ / cur_.f.width);
    int by = static_cast<int>(x.y() * bins_y_ / cur_.f.height);
    bx = std::min(bins_x_ - 1, std::max(0, bx));
    by = std::min(bins_y_ - 1, std::max(0, by));
    const int b = by * bins_x_ + bx;
    corr_feat_[n] = j;
    corr_bin_[n] = b;
    bin_sum_[b] += r;
    ++bin_count_[b];
    ss += r.squaredNorm();
    ++n;
  }
  *sum_sq = ss;
  return n;
}

int Tracker::flag_coherent_bins(double var) {
  // Bit 1: the bin's mean residual fails the chi-square test; bit 2: so does a like-displaced
  // neighbour (cosine of the mean residuals), i.e. a moving region: the bin is dropped.
  const int B = bins_x_ * bins_y_;
  constexpr int kMinBinPoints = 4;
  for (int b = 0; b < B; ++b) {
    if (bin_count_[b] < kMinBinPoints) continue;
    const double z2 = bin_sum_[b].squaredNorm() / (bin_count_[b] * var);
    bin_flag_[b] = z2 > params_.submotion_chi2 ? 1 : 0;
  }
  int dropped_bins = 0;
  for (int b = 0; b < B; ++b) {
    if (!(bin_flag_[b] & 1)) continue;
    const int bx = b % bins_x_, by = b / bins_x_;
    bool coherent = false;
    for (int dy = -1; dy <= 1 && !coherent; ++dy) {
      for (int dx = -1; dx <= 1 && !coherent; ++dx) {
        const int nx = bx + dx, ny = by + dy;
        if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= bins_x_ || ny >= bins_y_) continue;
        const int nb = ny * bins_x_ + nx;
        if (!(bin_flag_[nb] & 1)) continue;
        const double c = bin_sum_[b].dot(bin_sum_[nb]) /
                         std::max(1e-12, bin_sum_[b].norm() * bin_sum_[nb].norm());
        coherent = c > 0.7;  // within about 45 degrees
      }
    }
    if (coherent) {
      bin_flag_[b] |= 2;
      ++dropped_bins;
    }
  }
  return dropped_bins;
}

int Tracker::drop_and_refit(Pose& T, int n, int inliers, bool* dropped_any) {
  // The n binned correspondences (bin_residuals) of the dropped bins leave this frame's
  // matches and eq. (1) is re-run, unless too little would be left to refit on.
  int dropped = 0;
  for (int k = 0; k < n; ++k) dropped += (bin_flag_[corr_bin_[k]] & 2) ? 1 : 0;
  if (n - dropped < params_.min_inliers) return inliers;
  for (int k = 0; k < n; ++k) {
    if (!(bin_flag_[corr_bin_[k]] & 2)) continue;
    reject_match(corr_feat_[k]);
  }
  *dropped_any = true;
  return optimise(T);
}

std::shared_ptr<const MapSnapshot> Tracker::relocalization_map(uint32_t* epoch) {
  // The current map, unless earlier maps are kept and place recognition over all epochs ranks
  // a kept map's keyframe first.
  *epoch = epoch_;
  if (!has_kept_maps() || !snap_->places) return snap_;
  const int64_t best = reloc_.best_epoch(cur_.f, *snap_->places);
  if (best < 0 || static_cast<uint32_t>(best) == epoch_) return snap_;
  for (const auto& k : snap_->kept) {
    if (k->epoch != static_cast<uint32_t>(best)) continue;
    *epoch = k->epoch;
    return k;
  }
  return snap_;
}

bool Tracker::relocalize() {
  uint32_t epoch = epoch_;
  std::shared_ptr<const MapSnapshot> map = relocalization_map(&epoch);
  if (!map || map->rows() < params_.reloc_min_inliers) return false;
  if (static_cast<int>(row_stamp_.size()) < map->rows()) {
    row_stamp_.resize(static_cast<size_t>(map->rows()) * 2, -1);  // map above its cap
    row_rejected_.resize(row_stamp_.size(), -1);
  }
  // The map tried is the active one while relocalizing (projection search); restored on failure.
  std::shared_ptr<const MapSnapshot> current = snap_;
  snap_ = std::move(map);
  if (!relocalize_in(epoch)) {
    snap_ = std::move(current);
    return false;
  }
  if (epoch != epoch_) {
    RDSLAM_LOG_INFO("tracker: relocalized in the kept map of epoch %u (was epoch %u)", epoch,
                    epoch_);
    epoch_ = epoch;
  }
  return true;
}

bool Tracker::relocalize_in(uint32_t epoch) {
  const int n = reloc_.match(cur_.f, *snap_, epoch, reloc_pairs_.data(),
                             static_cast<int>(reloc_pairs_.size() / 2));
  if (n < params_.reloc_min_matches) return false;
  // reloc_pairs_ holds (feature, snapshot row) pairs.
  for (int k = 0; k < n; ++k) {
    set_correspondence(k, reloc_pairs_[2 * k], snap_->p_world[reloc_pairs_[2 * k + 1]]);
  }
  Pose T;
  estimator_.reset_prior();  // the previous frames' bin prior says nothing about this view
  tight_.reset_prior();
  const int inl =
      estimator_.estimate(corr_p_.data(), corr_x_.data(), corr_s_.data(), n, T, corr_inl_.data());
  if (inl < params_.robust_min_inliers) return false;
  cur_.reset_matches(cur_.f.count);
  for (int k = 0; k < n; ++k) {
    if (!corr_inl_[k]) continue;
    const int j = reloc_pairs_[2 * k], r = reloc_pairs_[2 * k + 1];
    cur_.pid[j] = snap_->ids[r];
    cur_.p[j] = snap_->p_world[r];
    cur_.row[j] = r;
    cur_.best_dist[j] = 0.f;
  }
  ++frame_no_;  // fresh row stamps for the projection search
  match_local_map(T, params_.local_search_px * 2.0);
  int ok = optimise(T);
  match_local_map(T, params_.local_search_px);
  ok = optimise(T);
  if (ok < params_.reloc_min_inliers) return false;
  cur_.T = T;
  stats_.inliers = ok;
  return true;
}

void Tracker::start_from_init(const InitResult& init, const Frame& frame) {
  KeyframeCandidate* slot = link_->candidates.back();
  if (!slot) return;  // mapper still busy with an old map: try again next frame
  slot->kind = KeyframeCandidate::Kind::kInit;
  slot->epoch = epoch_;
  slot->levels = levels_;
  slot->stamp_ns = frame.stamp_ns;
  slot->frame_no = track_no_;
  slot->T_cam_world = init.T1;
  slot->features.copy_from(cur_.f);
  slot->point_of.assign(cur_.f.count, -1);
  slot->features0.copy_from(*init.reference);
  slot->stamp0_ns = init.reference_stamp_ns;
  slot->frame_no0 = track_no_ - initializer_.reference_age();
  ref_image_.copyTo(slot->image0);
  frame.image.copyTo(slot->image);
  slot->init_points = init.points;
  for (size_t k = 0; k < init.points.size(); ++k) slot->point_of[init.points[k].feat1] = int64_t(k);
  link_->candidates.commit();
  link_->bell.ring();
  if (params_.sync_mapper) wait_for_mapper();

  cur_.reset_matches(cur_.f.count);
  for (size_t k = 0; k < init.points.size(); ++k) {
    const int j = init.points[k].feat1;
    cur_.pid[j] = static_cast<int64_t>(k);
    cur_.p[j] = init.points[k].p_world;
    cur_.row[j] = -1;
    cur_.best_dist[j] = 0.f;
  }
  cur_.T = init.T1;
  // Constant velocity from the initial motion spread over the frames it took.
  const int age = std::max(1, initializer_.reference_age());
  const Eigen::AngleAxisd aa(init.T1.R);
  velocity_.R = Eigen::AngleAxisd(aa.angle() / age, aa.axis()).toRotationMatrix();
  velocity_.t = init.T1.t / age;
  velocity_dt_ns_ = (frame.stamp_ns - init.reference_stamp_ns) / age;
  state_ = TrackingState::kTracking;
  frames_since_kf_ = 0;
  stats_.inliers = static_cast<int>(init.points.size());
  RDSLAM_LOG_INFO("tracker: initialized with %zu points (%s, median parallax %.2f deg)",
                  init.points.size(), init.homography ? "homography" : "essential",
                  init.median_parallax_deg);
}

void Tracker::reset_map(const char* why) {
  KeyframeCandidate* slot = link_->candidates.back();
  if (!slot) return;
  const uint32_t old_epoch = epoch_;
  epoch_ = ++max_epoch_;  // never an earlier map's number (they may be kept)
  slot->kind = KeyframeCandidate::Kind::kReset;
  slot->epoch = epoch_;
  link_->candidates.commit();
  link_->bell.ring();
  snap_.reset();
  initializer_.reset();
  have_last_ = false;
  state_ = TrackingState::kInitializing;
  lost_frames_ = 0;
  RDSLAM_LOG_WARN("tracker: %s (map epoch %u): re-initializing a new map, epoch %u", why, old_epoch,
                  epoch_);
}

void Tracker::maybe_send_keyframe(const Frame& frame) {
  ++frames_since_kf_;
  if (!snap_ || snap_->kf_ids.empty()) return;
  const MapSnapshot& s = *snap_;
  kf_votes_.assign(s.kf_ids.size(), 0);  // capacity reserved: no allocation below the cap
  for (int j = 0; j < cur_.f.count; ++j) {
    const int r = cur_.row[j];
    if (cur_.pid[j] < 0 || r < 0) continue;
    for (int k = s.obs_start[r]; k < s.obs_start[r + 1]; ++k) ++kf_votes_[s.obs_kf[k]];
  }
  int ref = 0;
  for (size_t k = 1; k < kf_votes_.size(); ++k) {
    if (kf_votes_[k] > kf_votes_[ref]) ref = static_cast<int>(k);
  }
  ref_kf_shared_ = kf_votes_[ref];
  ref_kf_points_ = s.kf_points[ref];
  if (ref_kf_shared_ > 0) {
    ref_kf_id_ = s.kf_ids[ref];
    T_cam_ref_ = cur_.T * s.kf_pose[ref].inverse();
    rot_ref_kf_id_ = ref_kf_id_;  // rotation-only poses are reported against it
    rot_ref_T_ = s.kf_pose[ref];
  }
  const bool few_common = ref_kf_shared_ < params_.m1 ||
                          stats_.inliers < params_.keyframe_overlap_ratio * ref_kf_points_;
  // A young map rests on the two-view initialization's short baseline: its scale and depths
  // are refined only by the keyframes that follow, so they are proposed sooner.
  const bool young = link_->keyframes.load(std::memory_order_relaxed) < params_.young_map_keyframes;
  const int interval = young ? params_.young_map_keyframe_interval : params_.max_keyframe_interval;
  if (!few_common && frames_since_kf_ < interval) return;
  if (link_->localize_only.load(std::memory_order_relaxed)) return;  // the map is frozen
  if (params_.sync_mapper) wait_for_mapper();
  KeyframeCandidate* slot = link_->candidates.back();
  if (!slot) return;  // the mapper has not taken the previous candidate yet
  slot->kind = KeyframeCandidate::Kind::kKeyframe;
  slot->epoch = epoch_;
  slot->stamp_ns = frame.stamp_ns;
  slot->frame_no = track_no_;
  slot->T_cam_world = cur_.T;
  slot->features.copy_from(cur_.f);
  slot->point_of.resize(cur_.f.count);
  std::copy(cur_.pid.begin(), cur_.pid.begin() + cur_.f.count, slot->point_of.begin());
  frame.image.copyTo(slot->image);
  link_->candidates.commit();
  link_->bell.ring();
  frames_since_kf_ = 0;
  ++stats_.candidates_sent;
  if (params_.sync_mapper) wait_for_mapper();
}

void Tracker::maybe_send_observation(const Frame& frame) {
  if (link_->observe_every_n <= 0 || !snap_) return;
  if (link_->localize_only.load(std::memory_order_relaxed)) return;  // the map is frozen
  if (++frames_since_obs_ < link_->observe_every_n || frames_since_kf_ == 0) return;
  FrameObservation* o = link_->observations.back();
  if (!o) {
    link_->observations_skipped.fetch_add(1, std::memory_order_relaxed);
    return;  // the mapper is behind: the next observation is newer anyway
  }
  frames_since_obs_ = 0;
  o->epoch = epoch_;
  o->stamp_ns = frame.stamp_ns;
  o->frame_no = track_no_;
  o->T_cam_world = cur_.T;
  frame.image.copyTo(o->image);
  const size_t cap = cur_.pid.size();  // the feature cap: the slot grows once
  if (o->un.size() < cap) {
    o->un.resize(cap);
    o->point_of.resize(cap);
  }
  int n = 0;
  for (int j = 0; j < cur_.f.count; ++j) {
    if (cur_.pid[j] < 0) continue;
    o->un[n] = cur_.f.un[j];
    o->point_of[n] = cur_.pid[j];
    ++n;
  }
  o->tracked = n;
  const MapSnapshot& s = *snap_;
  if (o->rejected_ids.size() < cap) o->rejected_ids.resize(cap);
  int nr = 0;
  for (int r = 0; r < s.rows() && nr < static_cast<int>(cap); ++r) {
    if (row_rejected_[r] == track_no_) o->rejected_ids[nr++] = s.ids[r];
  }
  o->rejected = nr;
  link_->observations.commit();
  link_->observations_sent.fetch_add(1, std::memory_order_relaxed);
  link_->bell.ring();
  // Lossless replay maps like the offline run (core/slam.h run_offline): the updater's
  // invalidations reach the index before the next frame, so replays are deterministic.
  if (params_.sync_mapper) wait_for_mapper();
}

void Tracker::wait_for_mapper() {
  // Sync mode: block until the ring is empty and the mapper idle (bounded waits, so a
  // stopped mapper cannot hang the tracker for more than a few seconds).
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 50; ++i) {
    const uint32_t ticket = link_->mapped.ticket();
    if (link_->candidates.size_approx() == 0 && link_->observations.size_approx() == 0 &&
        link_->mapper_busy.load(std::memory_order_acquire) == 0) {
      break;
    }
    link_->mapped.wait(ticket, 100);
  }
  wait_ms_ +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Tracker::fill_result(TrackResult& r, bool found) const {
  r.state = state_;
  // A found pose is this frame's; otherwise the last good one (LOST, INITIALIZING).
  const Pose& T = (found || (state_ != TrackingState::kLost && have_last_)) ? cur_.T : last_.T;
  const Pose Twc = T.inverse();
  r.p_world_cam = Twc.t;
  r.q_world_cam = Eigen::Quaterniond(Twc.R).normalized();
  r.inliers = stats_.inliers;
  r.quality = cur_.f.count > 0 ? double(stats_.inliers) / cur_.f.count : 0.0;
  r.covariance.fill(-1.0);  // stays -1 unless found and computable (core/pose_refine.h)
  if (found) {
    PoseInformation info(kInlierChi2);  // over the final eq. (1) inliers at the published pose
    for (int j = 0; j < cur_.f.count; ++j) {
      if (cur_.pid[j] < 0) continue;
      info.add(K_, T, cur_.p[j], Eigen::Vector2d(cur_.f.un[j].x, cur_.f.un[j].y), cur_.f.scale[j]);
    }
    info.covariance(T, &r.covariance);
  }
  r.map_points = link_->points.load(std::memory_order_relaxed);
  r.keyframes = link_->keyframes.load(std::memory_order_relaxed);
  r.invalidated_points = link_->invalidated_points.load(std::memory_order_relaxed);
  r.mapper_wait_ms = wait_ms_;
  r.epoch = epoch_;
  r.map_merges = link_->merges.load(std::memory_order_relaxed);
  r.ref_keyframe = ref_kf_id_;  // -1 unless this frame's pose was found (reset per frame)
  const Pose T_ref_cam = T_cam_ref_.inverse();
  r.q_ref_cam = Eigen::Quaterniond(T_ref_cam.R).normalized();
  r.p_ref_cam = T_ref_cam.t;
}

void Tracker::start_with_map() {
  state_ = TrackingState::kLost;
  have_last_ = false;
  lost_frames_ = 0;
  lost_since_pending_ = true;  // new_map_after_s counts from the first frame's stamp
}

TrackResult Tracker::track(const Frame& frame) {
  const uint32_t resets = link_->reset_requests.load(std::memory_order_relaxed);
  if (resets != resets_served_ && state_ != TrackingState::kInitializing) {
    reset_map("reset requested");  // tried again at the next frame while the candidate ring is full
    if (state_ == TrackingState::kInitializing) resets_served_ = resets;
  } else {
    resets_served_ = resets;
  }
  ++frame_no_;
  ++track_no_;
  wait_ms_ = 0.0;
  ref_kf_id_ = -1;
  extract(frame);
  bool found = false;
  if (state_ == TrackingState::kInitializing && has_kept_maps() && relocalize()) {
    // Recovery: a new map is initializing, but the frame was found in a kept earlier map.
    initializer_.reset();
    state_ = TrackingState::kRelocalized;
    velocity_ = Pose();
    velocity_dt_ns_ = 0;
    lost_frames_ = 0;
    found = true;
    maybe_send_keyframe(frame);
  } else if (state_ == TrackingState::kInitializing) {
    found = track_initializing(frame);  // start_from_init hands this frame to the mapper itself
    if (found) {
      ref_kf_id_ = 1;  // this frame is the new map's second keyframe
      T_cam_ref_ = Pose{};
    }
  } else if (state_ == TrackingState::kLost) {
    found = handle_lost();
    if (found) {
      maybe_send_keyframe(frame);
      maybe_send_observation(frame);
    }
  } else {
    // Rotation mode is entered only from a turn on the spot (judged on the last motion, before
    // track_with_map replaces it) and left as soon as the full pose is found again.
    const bool rotation = params_.rotation_only && (rotation_mode_ || rotation_entry_ok());
    const Pose velocity = velocity_;
    const int64_t velocity_dt_ns = velocity_dt_ns_;
    found = track_with_map();
    if (found && rotation_mode_ && !rotation_exit_ok()) {
      found = false;  // a full pose far from the held centre: not trusted, still turning
      velocity_ = velocity;
      velocity_dt_ns_ = velocity_dt_ns;
    }
    if (found) {
      rotation_mode_ = false;
    } else if (rotation) {
      found = track_rotation_only();
    }
    if (!found) rotation_mode_ = false;
    if (found && !rotation_mode_) {
      maybe_send_keyframe(frame);
      maybe_send_observation(frame);
    } else if (found && rot_ref_kf_id_ >= 0) {
      // Rotation-only poses go to no mapper; reported against the last reference keyframe.
      ref_kf_id_ = rot_ref_kf_id_;
      T_cam_ref_ = cur_.T * rot_ref_T_.inverse();
    }
  }
  stats_.rotation_mode = found && rotation_mode_;
  TrackResult result;
  fill_result(result, found);
  if (found) {
    std::swap(cur_, last_);  // this frame's matches guide the next frame's motion search
    have_last_ = true;
  }
  return result;
}

void Tracker::extract_features(const cv::Mat& image, Features& out) {
  const cv::Mat* img = &image;
  if (image.type() == CV_8UC3) {
    cv::cvtColor(image, gray_, cv::COLOR_BGR2GRAY);
    img = &gray_;
  }
  (fast_motion_ ? *fast_extractor_ : extractor_).extract(*img, out);
}

void Tracker::extract(const Frame& frame) {
  // Feature extraction (Sec. 3; ORB or SIFT, FeatureParams) on the grey image; the newest
  // snapshot of the map's points (the mapper's bundle adjustment may have moved them).
  extract_features(frame.image, cur_.f);
  cur_.stamp_ns = frame.stamp_ns;
  cur_.reset_matches(cur_.f.count);
  refresh_snapshot();
  stats_.matches_motion = stats_.matches_local = 0;
}

bool Tracker::track_initializing(const Frame& frame) {
  // Two-view initialization (Sec. 3): the initializer keeps a reference frame until one
  // matches it with enough parallax; then the first two keyframes go to the mapper.
  stats_.inliers = 0;
  InitStatus s = initializer_.add_frame(cur_.f, frame.stamp_ns, init_result_);
  if (s == InitStatus::kFastMotion) {
    // Fast motion (TrackerParams::fast_motion_levels): from now on the deeper pyramid; the
    // reference frame and this one are described again on it and the attempt repeated.
    RDSLAM_LOG_INFO(
        "tracker: fast motion at initialization (median flow %.1f px): ORB pyramid "
        "of %d levels from now on",
        initializer_.last_attempt().median_flow_px, params_.fast_motion_levels);
    fast_motion_ = true;
    levels_ = params_.fast_motion_levels;
    initializer_.set_fast_motion_check(false);
    extract_features(ref_image_, ref_fast_);
    extract(frame);
    s = initializer_.retry_with_reference(ref_fast_, cur_.f, frame.stamp_ns, init_result_);
  }
  stats_.last_init = s;
  if (initializer_.reference_stamp() == frame.stamp_ns && s != InitStatus::kOk) {
    frame.image.copyTo(ref_image_);
  }
  if (s == InitStatus::kOk) start_from_init(init_result_, frame);
  return state_ == TrackingState::kTracking;
}

bool Tracker::track_with_map() {
  // TRACKING / RELOCALIZED: a cascade of searches around the constant-velocity prediction
  // (motion model, widened motion search, local-map projection), each tried when the previous
  // one left too few inliers; then the pose is extended with the local map (Sec. 3).
  const Pose Tpred = predict_pose();
  stats_.predicted = Tpred;
  Pose T = Tpred;
  int inl = track_with_motion_model(Tpred, T);
  if (inl < params_.search_min_inliers && have_last_) inl = widened_motion_search(Tpred, T);
  if (inl < params_.search_min_inliers && snap_) inl = local_map_fallback(Tpred, T);
  if (inl >= params_.extend_min_inliers) inl = extend_with_local_map(T);
  return update_state(T, inl);
}

Pose Tracker::predict_pose() const {
  // Constant velocity in time: the last motion over this frame's interval since the last
  // tracked frame (several frame periods when frames were dropped in between).
  const double s =
      motion_scale(cur_.stamp_ns - last_.stamp_ns, velocity_dt_ns_, params_.prediction_max_scale);
  if (s == 1.0) return velocity_ * last_.T;
  return scale_motion(velocity_, s) * last_.T;
}

int Tracker::track_with_motion_model(const Pose& Tpred, Pose& T) {
  // The previous frame's tracked points, projected with the prediction, matched in a radius;
  // robust pose (Sec. 3/5) and eq. (1) on the matches.
  stats_.matches_motion = have_last_ ? match_motion(Tpred, params_.motion_search_px) : 0;
  if (stats_.matches_motion < params_.search_min_matches) return 0;
  return params_.robust_per_frame ? robust_optimise(T, Tpred) : optimise(T);
}

int Tracker::widened_motion_search(const Pose& Tpred, Pose& T) {
  // Sudden motion change: the same search in a window twice as wide, eq. (1) only.
  cur_.reset_matches(cur_.f.count);
  T = Tpred;
  stats_.matches_motion = match_motion(Tpred, 2.0 * params_.motion_search_px);
  return stats_.matches_motion >= params_.search_min_matches ? optimise(T) : 0;
}

int Tracker::local_map_fallback(const Pose& Tpred, Pose& T) {
  // Both motion searches failed (or there is no previous frame): the map's points projected
  // with the prediction, in a window four times the local search's, eq. (1) only.
  cur_.reset_matches(cur_.f.count);
  T = Tpred;
  match_local_map(Tpred, 4.0 * params_.local_search_px);
  return optimise(T);
}

int Tracker::extend_with_local_map(Pose& T) {
  // Every visible point of the active matching index, projected with the pose and matched in
  // a small radius; eq. (1) over all matches, then the coherent sub-motion test.
  ++frame_no_;  // new row stamps: motion matches are re-marked inside
  stats_.matches_local = match_local_map(T, params_.local_search_px);
  const int inl = optimise(T);
  return submotion_test(T, inl);
}

int Tracker::submotion_test(Pose& T, int inl) {
  if (params_.submotion_chi2 <= 0.0) return inl;
  // Two passes: the first drops the object's strongly displaced core; under the refit pose
  // its weaker border bins (mixed with background) stand out too (measured on rigid_object
  // seeds 1-6: mean ATE 0.451% with one pass, 0.397% with two, 0.437% with three).
  constexpr int kPasses = 2;
  for (int pass = 0; pass < kPasses && inl >= params_.min_inliers; ++pass) {
    bool dropped = false;
    inl = reject_submotion(T, inl, &dropped);
    if (!dropped) break;
  }
  return inl;
}

bool Tracker::update_state(const Pose& T, int inl) {
  // At least min_inliers after refinement: TRACKING with a new constant velocity; else LOST.
  stats_.inliers = inl;
  if (inl < params_.min_inliers) {
    state_ = TrackingState::kLost;
    have_last_ = false;
    lost_frames_ = 1;
    lost_since_ns_ = cur_.stamp_ns;
    return false;
  }
  cur_.T = T;
  velocity_ = T * last_.T.inverse();
  velocity_dt_ns_ = cur_.stamp_ns - last_.stamp_ns;
  state_ = TrackingState::kTracking;
  lost_frames_ = 0;
  return true;
}

bool Tracker::handle_lost() {
  // LOST: relocalization against the map (Sec. 3) or a kept earlier map; lost for too long
  // (reset_after_lost_frames with a map of at most 2 keyframes, new_map_after_s with any),
  // INITIALIZING a new map epoch.
  if (lost_since_pending_) {
    lost_since_ns_ = cur_.stamp_ns;
    lost_since_pending_ = false;
  }
  if (relocalize()) {
    state_ = TrackingState::kRelocalized;
    velocity_ = Pose();
    velocity_dt_ns_ = 0;
    lost_frames_ = 0;
    return true;
  }
  ++lost_frames_;
  // A frozen map (SlamLink::localize_only) is never replaced: keep relocalizing.
  if (link_->localize_only.load(std::memory_order_relaxed)) return false;
  // A tiny map after reset_after_lost_frames; any map after new_map_after_s (recovery: the
  // mapper keeps a map of more than 2 keyframes for relocalization and merging).
  const bool tiny = !snap_ || snap_->kf_ids.size() <= 2;
  const bool too_long =
      params_.new_map_after_s > 0.0 &&
      static_cast<double>(cur_.stamp_ns - lost_since_ns_) >= params_.new_map_after_s * 1e9;
  if ((lost_frames_ > params_.reset_after_lost_frames && tiny) || too_long) reset_map("lost");
  return false;
}

void Tracker::set_debug_sink(DebugFrameSink* sink, int recent_invalid) {
  debug_sink_ = sink;
  debug_rejected_.assign(sink ? static_cast<size_t>(fparams_.max_features) + 64 : 0, 0);
  link_->debug_recent_invalid.store(sink ? recent_invalid : 0, std::memory_order_relaxed);
}

void Tracker::emit_debug_frame(const Frame& frame, const TrackResult& result) {
  if (!debug_sink_) return;
  if (debug_sink_->recycles_records()) {
    DebugFrame* rec = debug_sink_->acquire_record(frame);
    if (rec) {
      fill_debug_frame(frame, result, *rec);
      debug_sink_->submit_record(rec);
    }
  } else {
    DebugFrame d;
    fill_debug_frame(frame, result, d);
    debug_sink_->on_debug_frame(std::move(d));
  }
  std::fill(debug_rejected_.begin(), debug_rejected_.end(), uint8_t{0});
}

void Tracker::fill_debug_frame(const Frame& frame, const TrackResult& result, DebugFrame& d) const {
  // track() swaps this frame into last_ exactly when it returns a found pose (TRACKING or
  // RELOCALIZED, including the initialization frame); otherwise the frame is still in cur_.
  const bool found =
      result.state == TrackingState::kTracking || result.state == TrackingState::kRelocalized;
  const FrameState& fs = found ? last_ : cur_;
  d.seq = frame.seq;
  d.stamp_ns = frame.stamp_ns;
  d.dataset_index = frame.dataset_index;
  d.result = result;
  d.has_pose = result.state != TrackingState::kInitializing;
  d.T_cam_world = last_.T;      // found: this frame (swapped in); LOST: the last good pose
  frame.image.copyTo(d.image);  // reuses a recycled record's buffer of the same size
  d.features.resize(static_cast<size_t>(fs.f.count));
  for (int j = 0; j < fs.f.count; ++j) {
    DebugFeature& df = d.features[static_cast<size_t>(j)];
    df.x = fs.f.kps[j].pt.x;
    df.y = fs.f.kps[j].pt.y;
    if (fs.pid[j] >= 0) {
      // A LOST frame's remaining matches did not support a pose: not inliers of anything.
      df.kind = found ? DebugFeatureKind::kInlier : DebugFeatureKind::kUnsupported;
    } else {
      df.kind = static_cast<DebugFeatureKind>(debug_rejected_[j]);
    }
  }
  d.snapshot = snap_;
}

}  // namespace rdslam
