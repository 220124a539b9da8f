// Rotation-only tracking of the Tracker (core/tracker.h, "Rotation-only tracking"): entering
// rotation mode, the rotation keyframes (tracker-local: features with their world bearings,
// points at infinity seen from the held centre) and the per-frame rotation estimate.
#include <algorithm>
#include <cmath>

#include "core/matching.h"
#include "core/pose_refine.h"
#include "core/tracker.h"

namespace rdslam {

double Tracker::median_depth(bool of_last, int min_points) {
  const FrameState& fs = of_last ? last_ : cur_;
  int n = 0;
  for (int j = 0; j < fs.f.count; ++j) {
    if (fs.pid[j] < 0) continue;
    const double z = (fs.T * fs.p[j]).z();
    if (z > 0.0) depth_scratch_[n++] = z;
  }
  if (n < min_points) return -1.0;
  std::nth_element(depth_scratch_.begin(), depth_scratch_.begin() + n / 2,
                   depth_scratch_.begin() + n);
  return depth_scratch_[n / 2];
}

bool Tracker::rotation_entry_ok() {
  // The recent motion (velocity_, smoothed over about 5 frames: single 6-DoF estimates from the
  // few points left at the map's edge are noisy) turned by at least rotation_min_deg per frame
  // while its translation, seen from the last frame's points (median depth), moved them by
  // well under the rotation: a turn on the spot. Without depths there is no telling.
  if (!have_last_ || state_ != TrackingState::kTracking) {
    rot_ema_angle_ = rot_ema_shift_ = 0.0;
    return false;
  }
  const double median = median_depth(true, params_.search_min_matches);
  if (median <= 0.0) return false;
  // Translation as an angle: what it moves a point at the median depth by.
  constexpr double kEma = 0.3;  // as in track_rotation_only
  const double angle = Eigen::AngleAxisd(velocity_.R).angle();
  rot_ema_angle_ += kEma * (angle - rot_ema_angle_);
  rot_ema_shift_ += kEma * (velocity_.t.norm() / median - rot_ema_shift_);
  return rot_ema_angle_ >= params_.rotation_min_deg * M_PI / 180.0 &&
         rot_ema_shift_ < params_.rotation_max_parallax_ratio * rot_ema_angle_;
}

bool Tracker::rotation_exit_ok() {
  // The full pose that would end rotation mode (cur_.T, from track_with_map) must lie near the
  // held centre, relative to the depth of its inliers: the centre held through the turn is off
  // by the camera's offset from the axis at most, while a pose matched to a repeated texture
  // elsewhere in the room jumps by a large part of the scene depth (measured on
  // synth:turn_in_place_offset: 0.9 m at 3 m).
  const double median = median_depth(false, params_.min_inliers);
  if (median <= 0.0) return false;
  // Once the turn has stopped (the smoothed rotation below rotation_min_deg per frame), the
  // camera may drive away from the held centre: then the full pose ends rotation mode anyway.
  return (cur_.T.centre() - rot_centre_).norm() < params_.rotation_exit_max_shift * median ||
         rot_ema_angle_ < params_.rotation_min_deg * M_PI / 180.0;
}

void Tracker::make_rotation_keyframe(const Features& f, const Pose& T_cam_world) {
  // Every feature of the frame, with its bearing in the world frame (unit vector).
  rot_kf_.copy_from(f);
  const Eigen::Matrix3d R_world_cam = T_cam_world.R.transpose();
  for (int i = 0; i < rot_kf_.count; ++i) {
    rot_bearing_[i] = R_world_cam * K_.unproject(rot_kf_.un[i].x, rot_kf_.un[i].y).normalized();
  }
  rot_kf_matches_ = -1;
  rot_kf_R_ = T_cam_world.R;
  ++stats_.rotation_keyframes;
}

int Tracker::match_bearings(const Eigen::Matrix3d& R_cam_world, double radius) {
  // The rotation keyframe's features at their bearings' predicted pixels, matched with this
  // frame's features not matched to a map point (one-to-one: the closest descriptor wins).
  const bool bin = fparams_.binary();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kMotion, bin);
  std::fill(bear_of_.begin(), bear_of_.begin() + cur_.f.count, -1);
  std::fill(bear_dist_.begin(), bear_dist_.begin() + cur_.f.count, 1e30f);
  for (int i = 0; i < rot_kf_.count; ++i) {
    const Eigen::Vector3d Xc = R_cam_world * rot_bearing_[i];
    if (Xc.z() <= 1e-6) continue;
    const Eigen::Vector2d uv = K_.project(Xc);
    if (!camera_.ideal_in_image(uv)) continue;
    const int lvl = rot_kf_.level[i];
    const int n = cur_.f.radius_search(
        float(uv.x()), float(uv.y()), float(radius * rot_kf_.scale[i]), bin ? lvl - 1 : -1,
        bin ? lvl + 1 : 1 << 20, cand_.data(), static_cast<int>(cand_.size()));
    const BestTwo best = best_of(rot_kf_.desc_ptr(i), cur_.f, cand_.data(), n, bin,
                                 [this](int j) { return cur_.pid[j] >= 0; });
    if (!rule.accepts(best) || best.d1 >= bear_dist_[best.index]) continue;
    bear_of_[best.index] = i;
    bear_dist_[best.index] = static_cast<float>(best.d1);
  }
  int m = 0;
  for (int j = 0; j < cur_.f.count; ++j) m += bear_of_[j] >= 0;
  return m;
}

int Tracker::estimate_rotation_pose(Pose& T, bool robust) {
  // Map points as directions from the held centre and the bearings: one rotation (centre
  // fixed). Outliers lose their match for this frame.
  int n = 0;
  for (int j = 0; j < cur_.f.count; ++j) {
    if (cur_.pid[j] >= 0) {
      set_correspondence(n, j, cur_.p[j] - rot_centre_);
      corr_bear_[n++] = -1;
    } else if (bear_of_[j] >= 0) {
      set_correspondence(n, j, rot_bearing_[bear_of_[j]]);
      corr_bear_[n++] = bear_of_[j];
    }
  }
  if (n < params_.search_min_matches) return 0;
  Eigen::Matrix3d R = T.R;
  const int inl = robust
                      ? estimate_rotation(K_, corr_p_.data(), corr_x_.data(), corr_s_.data(), n, R,
                                          corr_inl_.data(), kInlierChi2, 64, uint32_t(track_no_))
                      : refine_rotation(K_, corr_p_.data(), corr_x_.data(), corr_s_.data(), n, R,
                                        corr_inl_.data(), kInlierChi2);
  if (inl < params_.search_min_inliers) return 0;
  int bearings = 0;
  for (int k = 0; k < n; ++k) {
    const int j = corr_feat_[k];
    if (corr_inl_[k]) {
      bearings += corr_bear_[k] >= 0;
    } else if (corr_bear_[k] >= 0) {
      bear_of_[j] = -1;
    } else {
      cur_.pid[j] = -1;
      cur_.row[j] = -1;
      cur_.best_dist[j] = 1e30f;
    }
  }
  stats_.matches_bearing = bearings;
  T.R = R;
  T.t = -R * rot_centre_;
  return inl;
}

bool Tracker::track_rotation_only() {
  // Rotation mode lasts while the camera turns: once the smoothed rotation has fallen below
  // half the entry rate, the held centre is no longer implied by the motion (the robot may
  // drive off), so the frame is LOST and relocalization takes over.
  if (rotation_mode_ && rot_ema_angle_ < 0.5 * params_.rotation_min_deg * M_PI / 180.0) {
    return false;
  }
  // The last tracked frame becomes the first rotation keyframe; its centre is held.
  if (!rotation_mode_) {
    rot_centre_ = last_.T.centre();
    make_rotation_keyframe(last_.f, last_.T);
    rotation_mode_ = true;
  }
  Pose T = predict_pose();
  T.t = -T.R * rot_centre_;
  // A wide search around the prediction, a robust rotation; then the small search around it.
  const double radii[2] = {params_.motion_search_px, params_.local_search_px};
  int inl = 0;
  for (int pass = 0; pass < 2; ++pass) {
    cur_.reset_matches(cur_.f.count);
    ++frame_no_;  // new row stamps for the map-point search
    match_local_map(T, pass == 0 ? 4.0 * params_.local_search_px : params_.local_search_px);
    match_bearings(T.R, radii[pass]);
    inl = estimate_rotation_pose(T, pass == 0);
    if (inl < params_.min_inliers) break;
  }
  stats_.inliers = inl;
  if (inl < params_.min_inliers) return false;
  cur_.T = T;
  velocity_ = T * last_.T.inverse();
  velocity_dt_ns_ = cur_.stamp_ns - last_.stamp_ns;
  state_ = TrackingState::kTracking;
  have_last_ = true;
  lost_frames_ = 0;
  ++stats_.rotation_frames;
  rot_ema_angle_ += 0.3 * (Eigen::AngleAxisd(velocity_.R).angle() - rot_ema_angle_);
  // The next rotation keyframe when this one's matches have thinned out because the view
  // turned away (at least kRefreshMinDeg since it): matches lost to translation (parallax the
  // held centre cannot explain) make no new rotation keyframe, so a camera that drives off
  // while in rotation mode runs out of inliers and goes LOST (relocalization) instead of
  // being tracked with a wrong centre.
  constexpr double kRefreshMinDeg = 5.0;
  if (rot_kf_matches_ < 0) {
    rot_kf_matches_ = stats_.matches_bearing;
  } else if (stats_.matches_bearing < params_.rotation_refresh_ratio * rot_kf_matches_ &&
             Eigen::AngleAxisd(T.R * rot_kf_R_.transpose()).angle() >=
                 kRefreshMinDeg * M_PI / 180) {
    make_rotation_keyframe(cur_.f, cur_.T);
  }
  return true;
}

}  // namespace rdslam
