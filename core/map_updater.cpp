#include "core/map_updater.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

namespace rdslam {

namespace {
// Histograms sample every 4th pixel in x and y: the trigger is a global statistic, 1/16 of
// the pixels is plenty and keeps the per-frame cost small.
constexpr int kHistogramStride = 4;
// phi(x') is capped: Alg. 1 needs only whether a nearer point exists and where it projects.
constexpr int kMaxNeighbours = 64;
// A tracked feature this close (pixels at the point's keyframe scale) to an unmatched point's
// projection makes the point a duplicate (dynamic.prune_unmatched).
constexpr double kDuplicatePx = 3.0;
constexpr int kMaxSelected = 20;  // ChangeDetectionParams::closest_keyframes upper bound

// The cause recorded for an Algorithm 1 change verdict.
InvalidationCause cause_of(PointDecision d) {
  return d == PointDecision::kInvalidNothingInFront ? InvalidationCause::kNothingInFront
         : d == PointDecision::kInvalidSameObject   ? InvalidationCause::kSameObject
         : d == PointDecision::kInvalidStaticChange ? InvalidationCause::kStaticChange
                                                    : InvalidationCause::kNoOcclusionHandling;
}
}  // namespace

namespace {
CameraModel undistorted_camera(const PinholeIntrinsics& K) {
  CameraModel c;
  c.fx = K.fx;
  c.fy = K.fy;
  c.cx = K.cx;
  c.cy = K.cy;
  return c;
}
}  // namespace

MapUpdater::MapUpdater(const ChangeDetectionParams& params, const PinholeIntrinsics& K,
                       double redundant_fraction)
    : MapUpdater(params, undistorted_camera(K), redundant_fraction) {}

MapUpdater::MapUpdater(const ChangeDetectionParams& params, const CameraModel& camera,
                       double redundant_fraction)
    : params_(params),
      camera_(camera),
      lens_(camera.has_distortion()),
      K_{camera.fx, camera.fy, camera.cx, camera.cy},
      redundant_fraction_(redundant_fraction) {
  // Algorithm 1 compares D_c with the threshold of the score in use.
  if (params_.normalise_appearance) params_.tau_c = params_.tau_c_relative;
  cell_px_ = std::max(params_.r1, 4.0);
  selected_.resize(kMaxSelected);
  neighbours_.resize(kMaxNeighbours);
  if (lens_) {
    // The ideal pixels of the image's border bound those of every pixel (the lens maps the
    // image's inside to the inside of its border's image).
    double b[4] = {1e300, 1e300, -1e300, -1e300};
    auto add = [&](double x, double y) {
      Eigen::Vector2d u;
      if (!camera_.undistort(Eigen::Vector2d(x, y), &u)) return;
      b[0] = std::min(b[0], u.x());
      b[1] = std::min(b[1], u.y());
      b[2] = std::max(b[2], u.x());
      b[3] = std::max(b[3], u.y());
    };
    for (int x = 0; x < camera_.width; ++x) {
      add(x, 0);
      add(x, camera_.height - 1);
    }
    for (int y = 0; y < camera_.height; ++y) {
      add(0, y);
      add(camera_.width - 1, y);
    }
    if (b[0] <= b[2] && b[1] <= b[3]) std::copy(b, b + 4, ideal_box_);
  }
}

MapUpdater::Pixel MapUpdater::pixel_of_ideal(const Eigen::Vector2d& ideal) const {
  return {ideal, lens_ ? camera_.distort(ideal) : ideal};
}

MapUpdater::Pixel MapUpdater::pixel(const Eigen::Vector3d& p_cam) const {
  return pixel_of_ideal(K_.project(p_cam));
}

double MapUpdater::window_difference(const cv::Mat& image_a, const Pixel& a, const cv::Mat& image_b,
                                     const Pixel& b, double scale, int search_d,
                                     double accept) const {
  if (!lens_) {
    return appearance_difference(image_a, a.raw, image_b, b.raw, scale, params_.window, search_d,
                                 params_.normalise_appearance, accept);
  }
  // Raw offset at a -> ideal (J_a^-1) -> ideal at b (depth ratio) -> raw at b (J_b).
  const Eigen::Matrix2d J_a = camera_.distort_jacobian(a.ideal);
  const Eigen::Matrix2d J_b = camera_.distort_jacobian(b.ideal);
  if (!(std::abs(J_a.determinant()) > 1e-12)) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix2d warp = scale * J_b * J_a.inverse();
  return appearance_difference(image_a, a.raw, image_b, b.raw, warp, params_.window, search_d,
                               params_.normalise_appearance, accept);
}

void MapUpdater::reset() {
  confirm_.clear();
  kf_hist_.clear();
  for (Recent& r : history_) r.stamp_ns = -1;
  prev_frame_no_ = -1;
}

const ColorHistogram& MapUpdater::keyframe_histogram(const Keyframe& kf) {
  auto it = kf_hist_.find(kf.id);
  if (it != kf_hist_.end()) return it->second;
  ColorHistogram& h = kf_hist_[kf.id];
  compute_color_histogram(kf.image, kHistogramStride, h);
  return h;
}

void MapUpdater::build_grid(int width, int height) {
  if (!lens_) {
    ideal_box_[2] = width;
    ideal_box_[3] = height;
  }
  grid_cols_ = std::max(1, static_cast<int>(std::ceil((ideal_box_[2] - ideal_box_[0]) / cell_px_)));
  grid_rows_ = std::max(1, static_cast<int>(std::ceil((ideal_box_[3] - ideal_box_[1]) / cell_px_)));
  const size_t cells = size_t(grid_cols_) * grid_rows_;
  cell_start_.assign(cells + 1, 0);
  cell_fill_.assign(cells, 0);
  cell_items_.resize(tracked_.size());
  auto cell_of = [&](const Eigen::Vector2d& px) {
    const int cx =
        std::clamp(static_cast<int>((px.x() - ideal_box_[0]) / cell_px_), 0, grid_cols_ - 1);
    const int cy =
        std::clamp(static_cast<int>((px.y() - ideal_box_[1]) / cell_px_), 0, grid_rows_ - 1);
    return cy * grid_cols_ + cx;
  };
  for (const Tracked& t : tracked_) ++cell_start_[cell_of(t.pixel) + 1];
  for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  for (size_t i = 0; i < tracked_.size(); ++i) {
    const int c = cell_of(tracked_[i].pixel);
    cell_items_[cell_start_[c] + cell_fill_[c]++] = static_cast<int>(i);
  }
}

template <class F>
void MapUpdater::for_each_tracked_within(const Eigen::Vector2d& x, double radius, F&& f) const {
  const double r2 = radius * radius;
  const double gx = x.x() - ideal_box_[0], gy = x.y() - ideal_box_[1];
  const int x0 = std::max(0, static_cast<int>((gx - radius) / cell_px_));
  const int x1 = std::min(grid_cols_ - 1, static_cast<int>((gx + radius) / cell_px_));
  const int y0 = std::max(0, static_cast<int>((gy - radius) / cell_px_));
  const int y1 = std::min(grid_rows_ - 1, static_cast<int>((gy + radius) / cell_px_));
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const int c = cy * grid_cols_ + cx;
      for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const Tracked& t = tracked_[cell_items_[k]];
        if ((t.pixel - x).squaredNorm() <= r2 && !f(t)) return;
      }
    }
  }
}

int MapUpdater::gather_neighbours(const Eigen::Vector2d& x_prime, const Keyframe* first_kf) {
  int n = 0;
  for_each_tracked_within(x_prime, params_.r1, [&](const Tracked& t) {
    NeighbourPoint& nb = neighbours_[n++];
    nb.pixel = t.pixel;
    nb.depth_current = t.depth;
    nb.in_first_keyframe = false;
    if (first_kf != nullptr) {
      const Eigen::Vector3d pc = first_kf->T_cam_world * t.p_world;
      if (pc.z() > 1e-9) {
        nb.pixel_in_first_keyframe = K_.project(pc);
        nb.in_first_keyframe = true;
      }
    }
    return n < kMaxNeighbours;
  });
  return n;
}

bool MapUpdater::tracked_within(const Eigen::Vector2d& x, double radius) const {
  bool found = false;
  for_each_tracked_within(x, radius, [&](const Tracked&) {
    found = true;
    return false;  // one is enough
  });
  return found;
}

const Keyframe* MapUpdater::first_keyframe(Map& map, const MapPoint& p) const {
  if (const Keyframe* kf = map.keyframe(p.first_kf)) return kf;
  // The first keyframe was culled: the oldest keyframe still observing X stands in for it.
  const Keyframe* best = nullptr;
  for (const Observation& o : p.obs) {
    const Keyframe* kf = map.keyframe(o.kf);
    if (kf != nullptr && (best == nullptr || kf->id < best->id)) best = kf;
  }
  return best;
}

bool MapUpdater::counter_event(Map& map, int64_t id, LandmarkEvent e) {
  if (!params_.landmark_counters) return false;
  MapPoint* p = map.point(id);
  if (p == nullptr) return false;
  LandmarkCounters c;
  c.missed = static_cast<uint16_t>(std::clamp(p->missed, 0, 65535));
  c.moved = static_cast<uint16_t>(std::clamp(p->moved, 0, 65535));
  const bool discard =
      update_landmark_counters(c, e, params_.miss_threshold, params_.moved_threshold);
  p->missed = c.missed;
  p->moved = c.moved;
  return discard;
}

const char* to_string(InvalidationCause c) {
  switch (c) {
    case InvalidationCause::kNothingInFront:
      return "alg1:nothing-in-front";
    case InvalidationCause::kSameObject:
      return "alg1:same-object";
    case InvalidationCause::kNoOcclusionHandling:
      return "alg1:no-occlusion-handling";
    case InvalidationCause::kMovedRejected:
      return "counter:moved(rejected)";
    case InvalidationCause::kMovedFlow:
      return "counter:moved(flow)";
    case InvalidationCause::kMissed:
      return "counter:missed";
    case InvalidationCause::kStaticChange:
      return "alg1:static-change";
  }
  return "unknown";
}

void MapUpdater::invalidate(MapPoint& p, MapUpdateStats& st, std::vector<int64_t>* invalidated,
                            InvalidationCause cause, double d_c, int kf) {
  if (!p.valid) return;
  p.valid = false;
  ++st.points_invalidated;
  if (cause >= InvalidationCause::kMovedRejected) ++st.counter_discards;
  if (invalidated != nullptr) invalidated->push_back(p.id);
  if (records_ != nullptr) records_->push_back({p.id, cause, d_c, kf});
}

void MapUpdater::flow_events(Map& map, const UpdateFrame& f, MapUpdateStats& st,
                             std::vector<int64_t>* invalidated) {
  // Second paper, Sec. 3.3 / 4.2: while the camera is stationary, a landmark matched on a
  // region with dense optical flow is "moved". Flow between this observation and the previous
  // one; thresholds are per frame and scale with the number of frames between the two.
  const cv::Mat& img = *f.image;
  if (img.channels() == 3) {
    cv::cvtColor(img, cur_gray_, cv::COLOR_BGR2GRAY);
  } else {
    img.copyTo(cur_gray_);
  }
  const int64_t gap = f.frame_no >= 0 && prev_frame_no_ >= 0 ? f.frame_no - prev_frame_no_ : -1;
  if (gap > 0 && gap <= 8 && prev_gray_.size == cur_gray_.size) {
    ChangeDetectionParams scaled = params_;
    scaled.stationary_translation *= double(gap);
    scaled.stationary_rotation_deg *= double(gap);
    const Pose pw = prev_T_.inverse(), cw = f.T_cam_world.inverse();
    if (camera_is_stationary(scaled, pw.R, pw.t, cw.R, cw.t)) {
      cv::calcOpticalFlowFarneback(prev_gray_, cur_gray_, flow_, 0.5, 3, 15, 3, 5, 1.2, 0);
      st.flow_computed = true;
      fx_.resize(f.count);
      fy_.resize(f.count);
      keep_.assign(f.count, 1);
      for (int i = 0; i < f.count; ++i) {
        // The flow field is in raw pixels.
        const Eigen::Vector2d raw = pixel_of_ideal(Eigen::Vector2d(f.un[i].x, f.un[i].y)).raw;
        fx_[i] = static_cast<float>(raw.x());
        fy_[i] = static_cast<float>(raw.y());
        if (f.point_of[i] < 0) keep_[i] = 0;
      }
      reject_by_flow(flow_, fx_.data(), fy_.data(), f.count, params_.flow_threshold_px * gap,
                     keep_.data());
      for (int i = 0; i < f.count; ++i) {
        if (f.point_of[i] < 0 || keep_[i]) continue;
        ++st.flow_moved;
        MapPoint* p = map.point(f.point_of[i]);
        if (p != nullptr && counter_event(map, p->id, LandmarkEvent::kMatchedMoved)) {
          invalidate(*p, st, invalidated, InvalidationCause::kMovedFlow);
        }
      }
    }
  }
  std::swap(prev_gray_, cur_gray_);
  prev_T_ = f.T_cam_world;
  prev_frame_no_ = f.frame_no;
}

MapUpdateStats MapUpdater::update(Map& map, const cv::Mat& image, const Pose& T_cam_world,
                                  const Features& features, const std::vector<int64_t>& point_of,
                                  std::vector<int64_t>* invalidated) {
  UpdateFrame f;
  f.image = &image;
  f.T_cam_world = T_cam_world;
  f.un = features.un.data();
  f.point_of = point_of.data();
  f.count = std::min<int>(features.count, static_cast<int>(point_of.size()));
  return update(map, f, invalidated, nullptr);
}

double MapUpdater::ray_difference(Map& map, const MapPoint& p, const Keyframe& kf, int feat,
                                  const cv::Mat& image, const Pose& T_cam_world) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // Depth uncertainty of X along the keyframe's ray from its widest triangulation angle: a
  // bearing error of sigma px moves the depth by sigma / (f sin(parallax)) relative.
  const Eigen::Vector3d kf_c = kf.T_cam_world.centre();
  double best_sin = 0.0;
  for (const Observation& o : p.obs) {
    const Keyframe* other = map.keyframe(o.kf);
    if (other == nullptr || other == &kf) continue;
    const double c = parallax_cos(p.p_world, kf_c, other->T_cam_world.centre());
    best_sin = std::max(best_sin, std::sqrt(std::max(0.0, 1.0 - c * c)));
  }
  const double sigma = kf.features.scale[feat];
  const double rel =
      best_sin > 1e-6 ? params_.ray_search_sigmas * sigma / (K_.fx * best_sin) : kMaxRayDepthRatio;
  const double delta = std::clamp(rel, kMinRayDepthRatio, kMaxRayDepthRatio);
  const Eigen::Vector3d pk = kf.T_cam_world * p.p_world;
  if (pk.z() <= 1e-9) return kInf;
  // The ray through the keyframe's feature (unit depth bearing in world coordinates).
  const Eigen::Vector3d bearing =
      kf.T_cam_world.R.transpose() * K_.unproject(kf.features.un[feat].x, kf.features.un[feat].y);
  const double inv_near = 1.0 / (pk.z() / (1.0 + delta)), inv_far = 1.0 / (pk.z() * (1.0 + delta));
  const Eigen::Vector3d a = T_cam_world * (kf_c + bearing / inv_near);
  const Eigen::Vector3d b = T_cam_world * (kf_c + bearing / inv_far);
  if (a.z() <= 1e-9 || b.z() <= 1e-9) return kInf;
  const double len = (pixel(a).raw - pixel(b).raw).norm();
  // One sample per pixel of the segment (eq. (2)'s local search covers the pixel between),
  // at most kMaxRaySamples: the far end of a long segment is not the point any more.
  const int steps = std::clamp(static_cast<int>(std::ceil(len)), 1, kMaxRaySamples);
  const cv::Point2f& kp = kf.features.kps[feat].pt;
  const Pixel x_kf{Eigen::Vector2d(kf.features.un[feat].x, kf.features.un[feat].y),
                   Eigen::Vector2d(kp.x, kp.y)};
  double best = kInf;
  for (int s = 0; s <= steps; ++s) {
    const double inv_z = inv_near + (inv_far - inv_near) * s / steps;
    const double z = 1.0 / inv_z;
    const Eigen::Vector3d pc = T_cam_world * (kf_c + bearing * z);
    if (pc.z() <= 1e-9) continue;
    const double d = window_difference(kf.image, x_kf, image, pixel(pc), z / pc.z(),
                                       std::min(params_.search_d, 1), params_.tau_c);
    best = std::min(best, d);
    if (best <= params_.tau_c) break;  // found: X's surface is still there
  }
  return best;
}

void MapUpdater::remember(const UpdateFrame& f) {
  if (!params_.temporal_check || f.stamp_ns < 0) return;
  Recent& r = history_[history_head_];
  f.image->copyTo(r.image);
  r.T_cam_world = f.T_cam_world;
  r.stamp_ns = f.stamp_ns;
  history_head_ = (history_head_ + 1) % kHistory;
}

bool MapUpdater::usable(const Recent& r, const cv::Mat& image, int64_t stamp_ns) const {
  const int64_t max_gap = static_cast<int64_t>(params_.temporal_max_gap_s * 1e9);
  return r.stamp_ns >= 0 && r.stamp_ns < stamp_ns && stamp_ns - r.stamp_ns <= max_gap &&
         r.image.size == image.size && r.image.type() == image.type();
}

bool MapUpdater::recent_frames_agree(const Eigen::Vector3d& p_world, const cv::Mat& image,
                                     const Eigen::Vector2d& x, double depth,
                                     int64_t stamp_ns) const {
  if (!params_.check_new_points || stamp_ns < 0 || depth <= 1e-9) return true;
  // The oldest usable recent frame that sees the point: the widest baseline and the longest
  // time for an object to have moved.
  const Recent* oldest = nullptr;
  Pixel u_oldest;
  double z_oldest = 0.0;
  for (const Recent& r : history_) {
    if (!usable(r, image, stamp_ns)) continue;
    const Eigen::Vector3d q = r.T_cam_world * p_world;
    if (q.z() <= 1e-9) continue;
    const Pixel u = pixel(q);
    if (u.raw.x() < 0 || u.raw.y() < 0 || u.raw.x() >= image.cols || u.raw.y() >= image.rows) {
      continue;
    }
    if (oldest == nullptr || r.stamp_ns < oldest->stamp_ns) {
      oldest = &r;
      u_oldest = u;
      z_oldest = q.z();
    }
  }
  if (oldest == nullptr) return true;
  Pixel at{x, x};
  if (lens_ && !camera_.undistort(x, &at.ideal)) return true;
  const double d = window_difference(image, at, oldest->image, u_oldest, z_oldest / depth,
                                     params_.search_d, params_.tau_c);
  return !std::isfinite(d) || d <= params_.tau_c;
}

// The usable recent frame whose camera centre is farthest from c_cur (nullptr: none);
// *baseline receives that distance.
const MapUpdater::Recent* MapUpdater::widest_recent(const cv::Mat& image, int64_t stamp_ns,
                                                    const Eigen::Vector3d& c_cur,
                                                    double* baseline) const {
  const Recent* wide = nullptr;
  double best_b = 0.0;
  for (const Recent& r : history_) {
    if (!usable(r, image, stamp_ns)) continue;
    const double b = (r.T_cam_world.centre() - c_cur).norm();
    if (b > best_b) {
      best_b = b;
      wide = &r;
    }
  }
  *baseline = best_b;
  return wide;
}

// The usable recent frame other than `wide` whose baseline to c_cur is nearest half the widest
// (best_b); nullptr when none lies within best_b / 4 of that.
const MapUpdater::Recent* MapUpdater::mid_recent(const cv::Mat& image, int64_t stamp_ns,
                                                 const Eigen::Vector3d& c_cur, const Recent* wide,
                                                 double best_b) const {
  const Recent* mid = nullptr;
  double mid_err = std::numeric_limits<double>::infinity();
  for (const Recent& r : history_) {
    if (!usable(r, image, stamp_ns) || &r == wide) continue;
    const double e = std::abs((r.T_cam_world.centre() - c_cur).norm() - 0.5 * best_b);
    if (e < mid_err) {
      mid_err = e;
      mid = &r;
    }
  }
  return mid == nullptr || mid_err > 0.25 * best_b ? nullptr : mid;
}

NewSurface MapUpdater::new_surface(const Eigen::Vector3d& p_world, const Pixel& x_prime,
                                   double depth, const cv::Mat& image, const Pose& T_cam_world,
                                   int64_t stamp_ns, double* depth_seen) const {
  if (depth_seen != nullptr) *depth_seen = 0.0;
  if (!params_.temporal_check || stamp_ns < 0) return NewSurface::kUnknown;
  // 1. Moving or static: the newest recent frame's window at X's projection there, searched
  // around x' (scale: depth ratio, near 1 for frames this close).
  const Recent& last = history_[(history_head_ + kHistory - 1) % kHistory];
  if (!usable(last, image, stamp_ns)) return NewSurface::kUnknown;
  const Eigen::Vector3d pl = last.T_cam_world * p_world;
  if (pl.z() <= 1e-9) return NewSurface::kUnknown;
  const double d_t = window_difference(last.image, pixel(pl), image, x_prime, pl.z() / depth,
                                       params_.search_d, params_.tau_c);
  if (!std::isfinite(d_t)) return NewSurface::kUnknown;
  if (d_t > params_.tau_c) return NewSurface::kMoving;
  // 2. Static: where is it? Match the current window at x' along x's ray into the recent
  // frame with the widest baseline, over inverse depths from far behind X (1/(4 z_X)) to well
  // in front (1/(0.25 z_X)); the best match's depth against z_X decides.
  const Eigen::Vector3d c_cur = T_cam_world.centre();
  double best_b = 0.0;
  const Recent* wide = widest_recent(image, stamp_ns, c_cur, &best_b);
  if (wide == nullptr) return NewSurface::kUnknown;
  const Eigen::Vector3d ray =
      T_cam_world.R.transpose() * K_.unproject(x_prime.ideal.x(), x_prime.ideal.y());
  bool ok = true;
  // Distances along the ray in the wide view are measured in raw pixels (what the image
  // resolves).
  auto pixel_at = [&](double z, double* z_other) {
    const Eigen::Vector3d q = wide->T_cam_world * (c_cur + ray * z);
    *z_other = q.z();
    ok &= q.z() > 1e-9;
    return ok ? pixel(q) : Pixel{};
  };
  const double z_front = depth * (1.0 - params_.temporal_depth_margin);
  double zo = 0;
  const Eigen::Vector2d px_x = pixel_at(depth, &zo).raw, px_front = pixel_at(z_front, &zo).raw;
  const double inv_far = 1.0 / (4.0 * depth), inv_near = 1.0 / (0.25 * depth);
  const double len = (pixel_at(1.0 / inv_far, &zo).raw - pixel_at(1.0 / inv_near, &zo).raw).norm();
  if (!ok || len < 3.0) return NewSurface::kUnknown;  // no baseline to speak of
  // A sample every 2 px: eq. (2)'s local search (d = 1) covers the pixel between.
  const int steps = std::clamp(static_cast<int>(std::ceil(len / 2.0)), 2, kMaxDepthSamples);
  double best = std::numeric_limits<double>::infinity(), best_z = 0;
  Eigen::Vector2d best_px(0, 0);
  for (int s = 0; s <= steps; ++s) {
    const double z = 1.0 / (inv_far + (inv_near - inv_far) * s / steps);
    double zw = 0;
    const Pixel px = pixel_at(z, &zw);
    if (!ok) return NewSurface::kUnknown;
    const double d = window_difference(image, x_prime, wide->image, px, z / zw, 1);
    if (d < best) {
      best = d;
      best_z = z;
      best_px = px.raw;
    }
  }
  if (!(best <= params_.tau_c)) return NewSurface::kUnknown;  // no consistent static match
  // A third view: a moving object's own motion along the epipolar line mimics a depth in two
  // views, not in three. The recent frame whose baseline is nearest half the widest must see
  // the window at the depth found too.
  const Recent* mid = mid_recent(image, stamp_ns, c_cur, wide, best_b);
  if (mid == nullptr) return NewSurface::kUnknown;
  const Eigen::Vector3d qm = mid->T_cam_world * (c_cur + ray * best_z);
  if (qm.z() <= 1e-9) return NewSurface::kUnknown;
  const double d_mid = window_difference(image, x_prime, mid->image, pixel(qm), best_z / qm.z(),
                                         params_.search_d, params_.tau_c);
  if (!(d_mid <= params_.tau_c)) return NewSurface::kUnknown;
  if (depth_seen != nullptr) *depth_seen = best_z;
  // In front: the match lies clearly (2 px) on the near side of X's depth. At or behind: only
  // when the baseline separates X's depth from the "in front" boundary by 2 px.
  if (best_z < z_front) {
    return (best_px - px_x).norm() >= 2.0 ? NewSurface::kInFront : NewSurface::kUnknown;
  }
  return (px_x - px_front).norm() >= 2.0 ? NewSurface::kBehind : NewSurface::kUnknown;
}

MapUpdateStats MapUpdater::update(Map& map, const UpdateFrame& frame,
                                  std::vector<int64_t>* invalidated,
                                  std::vector<InvalidationRecord>* records) {
  MapUpdateStats st;
  records_ = records;
  if (frame.image == nullptr || frame.image->empty() || map.keyframes.empty()) return st;
  if (!params_.map_update) {
    // --no-map-update: nothing is checked, but check_new_points still needs recent frames.
    if (params_.check_new_points) remember(frame);
    return st;
  }
  const cv::Mat& image = *frame.image;
  Call c{map,
         frame,
         image,
         frame.T_cam_world,
         frame.T_cam_world.R.row(2).transpose(),
         frame.T_cam_world.centre(),
         st,
         invalidated};
  // This frame joins the recent frames of the temporal check when the call ends.
  struct Remember {
    MapUpdater& u;
    const UpdateFrame& f;
    ~Remember() { u.remember(f); }
  } remember_frame{*this, frame};

  // The steps of the header's list: 4 (moved events), 1, the tracked points (and 4's still
  // events), 2, 3 with the verdicts applied per point, 5, 6.
  moved_events(c);
  const int nsel = select_keyframes(c);
  collect_tracked(c);
  if (nsel == 0) return st;
  compute_color_histogram(image, kHistogramStride, current_hist_);
  if (!current_hist_.valid) return st;
  std::sort(tracked_ids_sorted_.begin(), tracked_ids_sorted_.end());
  build_grid(image.cols, image.rows);

  gather_candidates(c, nsel);
  judge_candidates(c);
  purge_confirmations(map);
  apply_keyframe_rule(map, st);
  erase_pruned(map, st);
  return st;
}

// Step 4, matched events (second paper's counters): a point the robust estimator rejected in
// this frame is "moved" (matched where the camera motion says it is not), as is, with
// flow_rejection and a stationary camera, a tracked point on dense optical flow; too many
// moved events in a row discard it.
void MapUpdater::moved_events(Call& c) {
  if (!params_.landmark_counters) return;
  if (params_.flow_rejection && c.frame.frame_no >= 0) {
    flow_events(c.map, c.frame, c.st, c.invalidated);
  }
  for (int i = 0; i < c.frame.rejected_count; ++i) {
    MapPoint* p = c.map.point(c.frame.rejected[i]);
    if (p != nullptr && p->valid && counter_event(c.map, p->id, LandmarkEvent::kMatchedMoved)) {
      invalidate(*p, c.st, c.invalidated, InvalidationCause::kMovedRejected);
    }
  }
}

// Step 1: the valid keyframes with an image (kf_ids_, z_axes_, centres_) and, of those, the
// `closest_keyframes` whose optical axis is within keyframe_view_angle_deg of the frame's,
// nearest camera centres first (selected_: indices into kf_ids_). Returns their number.
int MapUpdater::select_keyframes(Call& c) {
  kf_ids_.clear();
  z_axes_.clear();
  centres_.clear();
  for (auto& kv : c.map.keyframes) {
    const Keyframe& kf = kv.second;
    if (!kf.valid || kf.image.empty() || kf.image.channels() != c.image.channels()) continue;
    kf_ids_.push_back(kf.id);
    z_axes_.push_back(kf.T_cam_world.R.row(2).transpose());  // camera Z axis in world
    centres_.push_back(kf.T_cam_world.centre());
  }
  // Histogram cache entries of erased keyframes are dropped (bounded by max_keyframes).
  for (auto it = kf_hist_.begin(); it != kf_hist_.end();) {
    it = c.map.keyframes.count(it->first) ? std::next(it) : kf_hist_.erase(it);
  }
  const int nsel = select_closest_keyframes(
      c.cur_z, c.cur_c, z_axes_.data(), centres_.data(), static_cast<int>(kf_ids_.size()),
      params_.keyframe_view_angle_deg, params_.closest_keyframes, selected_.data(), kMaxSelected);
  c.st.keyframes_selected = nsel;
  return nsel;
}

// The frame's tracked points (tracked_, tracked_ids_sorted_ unsorted): phi(x')'s candidates
// and the set Alg. 1 skips. Step 4: each is "still" for the counters unless on flow.
void MapUpdater::collect_tracked(Call& c) {
  tracked_.clear();
  tracked_ids_sorted_.clear();
  for (int i = 0; i < c.frame.count; ++i) {
    if (c.frame.point_of[i] < 0) continue;
    MapPoint* p = c.map.point(c.frame.point_of[i]);
    if (p == nullptr) continue;
    p->unmatched = 0;
    const bool flowing = c.st.flow_computed && keep_[i] == 0;
    if (params_.landmark_counters && !flowing) {
      counter_event(c.map, p->id, LandmarkEvent::kMatchedStill);
    }
    const Eigen::Vector3d pc = c.T_cam_world * p->p_world;
    if (pc.z() <= 1e-9) continue;
    Tracked t;
    t.pixel = Eigen::Vector2d(c.frame.un[i].x, c.frame.un[i].y);
    t.p_world = p->p_world;
    t.depth = pc.z();
    t.id = p->id;
    tracked_.push_back(t);
    tracked_ids_sorted_.push_back(p->id);
  }
}

// The histogram trigger of keyframe kf (histogram_threshold 0: every keyframe is checked,
// even an identical image).
bool MapUpdater::triggers(const Keyframe& kf) {
  const ColorHistogram& kh = keyframe_histogram(kf);
  return kh.valid && (params_.histogram_threshold <= 0 ||
                      histogram_difference(kh, current_hist_) > params_.histogram_threshold);
}

// An untracked point projecting into the view (window inside the image): its camera-frame
// position and pixel. False for a point tracked in this frame (present) or out of view.
bool MapUpdater::untracked_in_view(const Call& c, const MapPoint& p, Eigen::Vector3d& pc,
                                   Pixel& xp) const {
  if (std::binary_search(tracked_ids_sorted_.begin(), tracked_ids_sorted_.end(), p.id)) {
    return false;
  }
  const int h = params_.window / 2;
  pc = c.T_cam_world * p.p_world;
  if (pc.z() <= 1e-9) return false;
  xp = pixel(pc);
  const Eigen::Vector2d& r = xp.raw;
  return r.x() >= h && r.y() >= h && r.x() < c.image.cols - h && r.y() < c.image.rows - h;
}

// A point of keyframe `kf` (feature i) that is valid, established, untracked and in view
// (pc, xp from untracked_in_view) becomes a candidate, with eq. (2) against kf where the view
// test lets Alg. 1 reach it.
void MapUpdater::add_candidate(Call& c, const Keyframe& kf, int i, const MapPoint& p,
                               const Eigen::Vector3d& pc, const Pixel& xp) {
  const Eigen::Vector3d kf_c = kf.T_cam_world.centre();
  if (p.obs.size() < static_cast<size_t>(std::max(1, params_.min_observations))) {
    ++c.st.points_not_established;
    return;
  }
  const Eigen::Vector3d pk = kf.T_cam_world * p.p_world;
  if (pk.z() <= 1e-9) return;
  // The reference view must agree with the point: X reprojects onto the keyframe's feature
  // (chi2 95% for 2 dof at the feature's scale, the mapper's own triangulation gate);
  // otherwise X or that keyframe's pose is off and eq. (2) would compare other pixels.
  const Eigen::Vector2d un(kf.features.un[i].x, kf.features.un[i].y);
  const double sig = kf.features.scale[i];
  if ((K_.project(pk) - un).squaredNorm() > 5.991 * sig * sig) {
    ++c.st.points_inconsistent;
    return;
  }
  Candidate cand;
  cand.id = p.id;
  cand.kf = kf.id;
  cand.feat = i;
  cand.n_x = (kf_c - p.p_world).normalized();
  cand.n_xp = (c.cur_c - p.p_world).normalized();
  cand.xp = xp;
  cand.depth = pc.z();
  cand.d_c = std::numeric_limits<double>::infinity();
  // Eq. (2) only when the view test lets Alg. 1 reach it (it is the expensive part).
  if (cand.n_x.dot(cand.n_xp) >= params_.tau_n) {
    const cv::Point2f& kp = kf.features.kps[i].pt;
    cand.d_c = window_difference(kf.image, Pixel{un, Eigen::Vector2d(kp.x, kp.y)}, c.image, xp,
                                 pk.z() / pc.z(), params_.search_d, params_.tau_c);
  }
  candidates_.push_back(cand);
}

// Step 2, pass 1: every valid, established, untracked point of the triggered keyframes that
// projects into the view, with eq. (2) against each of those keyframes where the view test
// passes (candidates_; the checked keyframes in triggered_). A point is judged once per frame
// on its best reference (the smallest D_c): it changed only if it looks different from every
// selected keyframe that saw it (deviation: the listing loops keyframe by keyframe, so one
// oblique or badly exposed reference view alone would invalidate a point the others still see
// unchanged).
void MapUpdater::gather_candidates(Call& c, int nsel) {
  candidates_.clear();
  triggered_.clear();
  prune_.clear();
  for (int s = 0; s < nsel; ++s) {
    Keyframe* kf = c.map.keyframe(kf_ids_[selected_[s]]);
    if (kf == nullptr) continue;
    if (!triggers(*kf)) continue;
    ++c.st.keyframes_triggered;
    triggered_.push_back(kf->id);
    const int kn = std::min<int>(kf->features.count, static_cast<int>(kf->point_of.size()));
    for (int i = 0; i < kn; ++i) {
      const int64_t pid = kf->point_of[i];
      if (pid < 0) continue;
      MapPoint* p = c.map.point(pid);
      Eigen::Vector3d pc;
      Pixel xp;
      if (p == nullptr || !p->valid || !untracked_in_view(c, *p, pc, xp)) continue;
      add_candidate(c, *kf, i, *p, pc, xp);
    }
  }
  if (params_.check_all_in_view) gather_unselected(c);
}

// Option check_all_in_view: the valid points in view that none of the selected keyframes
// holds, each against its own nearest observing keyframe within the pre-selection's view
// angle. The paper checks the selected keyframes' points only: where the camera sees a place
// from a new viewpoint, the closest keyframes are newer ones that never saw X, and a change
// there (a box removed after the robot passed) would never be checked. Off by default: the
// points no nearby keyframe holds are also those a static surface hides from here, and Alg. 1
// then invalidates more occluded points (docs/slam.md).
void MapUpdater::gather_unselected(Call& c) {
  covered_.clear();
  for (const Candidate& cand : candidates_) covered_.push_back(cand.id);
  std::sort(covered_.begin(), covered_.end());
  const double min_cos = std::cos(params_.keyframe_view_angle_deg * M_PI / 180.0);
  for (auto& kv : c.map.points) {
    MapPoint& p = kv.second;
    Eigen::Vector3d pc;
    Pixel xp;
    if (!p.valid || std::binary_search(covered_.begin(), covered_.end(), p.id) ||
        !untracked_in_view(c, p, pc, xp)) {
      continue;
    }
    Keyframe* ref = nullptr;
    int feat = -1;
    double best_d = std::numeric_limits<double>::infinity();
    for (const Observation& o : p.obs) {
      Keyframe* kf = c.map.keyframe(o.kf);
      if (kf == nullptr || !kf->valid || kf->image.empty() ||
          kf->image.channels() != c.image.channels() ||
          Eigen::Vector3d(kf->T_cam_world.R.row(2).transpose()).dot(c.cur_z) < min_cos) {
        continue;
      }
      const double d = (kf->T_cam_world.centre() - c.cur_c).squaredNorm();
      if (d < best_d) {
        best_d = d;
        ref = kf;
        feat = o.feat;
      }
    }
    if (ref == nullptr || feat < 0 || feat >= ref->features.count || !triggers(*ref)) continue;
    if (std::find(triggered_.begin(), triggered_.end(), ref->id) == triggered_.end()) {
      triggered_.push_back(ref->id);
    }
    ++c.st.points_unselected;
    add_candidate(c, *ref, feat, p, pc, xp);
  }
}

// Steps 3 and 4, pass 2: each candidate point judged once, on its best reference (view test
// passed and smallest D_c first), and the verdict applied at once, in point id order.
void MapUpdater::judge_candidates(Call& c) {
  std::sort(candidates_.begin(), candidates_.end(), [&](const Candidate& a, const Candidate& b) {
    if (a.id != b.id) return a.id < b.id;
    const bool va = a.n_x.dot(a.n_xp) >= params_.tau_n, vb = b.n_x.dot(b.n_xp) >= params_.tau_n;
    if (va != vb) return va;
    const bool fa = std::isfinite(a.d_c), fb = std::isfinite(b.d_c);
    if (fa != fb) return fa;
    return a.d_c < b.d_c;
  });
  for (size_t k = 0; k < candidates_.size(); ++k) {
    if (k > 0 && candidates_[k].id == candidates_[k - 1].id) continue;
    const Candidate& cand = candidates_[k];
    MapPoint* p = c.map.point(cand.id);
    if (p == nullptr || !p->valid) continue;
    double d_c = cand.d_c;
    const PointDecision d = judge(c, cand, *p, d_c);
    apply_verdict(c, cand, *p, d, d_c);
  }
}

// Step 3 for one point: Algorithm 1 on its best reference, D_c first refined by the ray
// search and, when X looks changed, phi(x') and the temporal check's NewSurface. `d_c` in:
// eq. (2) against the reference; out: after the ray search.
PointDecision MapUpdater::judge(Call& c, const Candidate& cand, const MapPoint& p, double& d_c) {
  const Keyframe* first = first_keyframe(c.map, p);
  Eigen::Vector2d x_first(-1e9, -1e9);
  if (first != nullptr) {
    const Eigen::Vector3d pf = first->T_cam_world * p.p_world;
    if (pf.z() > 1e-9) x_first = K_.project(pf);
  }
  if (params_.ray_search && std::isfinite(d_c) && d_c > params_.tau_c) {
    // Before calling X changed, look for its keyframe window along the keyframe's ray over
    // X's depth uncertainty: a point triangulated from a short baseline projects a few
    // pixels off its feature and would "change" in a static scene.
    const Keyframe* kf = c.map.keyframe(cand.kf);
    if (kf != nullptr)
      d_c = std::min(d_c, ray_difference(c.map, p, *kf, cand.feat, c.image, c.T_cam_world));
  }
  int nn = 0;
  NewSurface seen = NewSurface::kUnknown;
  double depth_seen = 0.0;
  if (std::isfinite(d_c) && d_c > params_.tau_c && params_.occlusion_handling) {
    nn = gather_neighbours(cand.xp.ideal, first);
    seen = new_surface(p.p_world, cand.xp, cand.depth, c.image, c.T_cam_world, c.frame.stamp_ns,
                       &depth_seen);
  }
  const PointDecision d = update_point_validity(params_, cand.n_x, cand.n_xp, d_c, cand.depth,
                                                x_first, neighbours_.data(), nn, seen);
  ++c.st.points_checked;
  ++c.st.decisions[static_cast<int>(d)];
  if (check_log_ != nullptr)
    check_log_->push_back({cand.id, d, seen, float(d_c), nn, float(cand.depth), float(depth_seen),
                           float(cand.xp.ideal.x()), float(cand.xp.ideal.y())});
  return d;
}

// Steps 3-4 and 6 for one verdict d on X (D_c = d_c): a change verdict confirmed
// confirm_checks times in a row sets V(X) = 0; "same appearance" is a "still" event and may
// mark X for pruning (prune_unmatched); "occluded by a moving object" is a "missed" event.
void MapUpdater::apply_verdict(Call& c, const Candidate& cand, MapPoint& p, PointDecision d,
                               double d_c) {
  if (is_invalidation(d)) {
    // A change is a lasting state; a verdict caused by something passing (a moving object's
    // edge, motion blur, a pose glitch) is not. V(X) = 0 after confirm_checks consecutive
    // change verdicts (1: the paper's immediate decision).
    if (++confirm_[cand.id] < params_.confirm_checks) return;
    confirm_.erase(cand.id);
    invalidate(p, c.st, c.invalidated, cause_of(d), d_c, cand.kf);
    return;
  }
  if (d == PointDecision::kKeepSameAppearance) {
    confirm_.erase(cand.id);
    counter_event(c.map, cand.id, LandmarkEvent::kMatchedStill);  // seen unchanged: present
    // Present and unoccluded, yet not tracked: counted only where the tracker would try to
    // match it (its viewing-angle and distance gates, core/tracker.cpp match_local_map).
    // Only where a tracked feature sits on the same pixel: X duplicates a point the tracker
    // uses (a surface mapped twice, e.g. after relocalizing); a lone unmatched point may still
    // be matched from another view and is kept.
    const double dist = (c.cur_c - p.p_world).norm();
    const Keyframe* kf = c.map.keyframe(cand.kf);
    const double r = kDuplicatePx * (kf != nullptr ? kf->features.scale[cand.feat] : 1.f);
    if (params_.prune_unmatched && p.normal.dot(cand.n_xp) >= 0.5 && dist >= p.min_dist &&
        dist <= p.max_dist && tracked_within(cand.xp.ideal, r) &&
        ++p.unmatched > params_.miss_threshold) {
      prune_.push_back(cand.id);
    }
  }
  if (d == PointDecision::kKeepOccludedMoving && params_.count_missed &&
      counter_event(c.map, cand.id, LandmarkEvent::kMissed)) {
    // Second paper's miss counter, restricted to the one case Algorithm 1 cannot decide:
    // X looks different and nothing tracked is near it. A moving occluder passes; when the
    // case persists for miss_threshold checks the "occluder" has not moved on, i.e. X's
    // surface is gone and nothing trackable replaced it (e.g. a plain wall).
    invalidate(p, c.st, c.invalidated, InvalidationCause::kMissed, d_c, cand.kf);
  }
}

// Confirmation counts of points that became invalid or were erased are dropped once the
// table outgrows the map.
void MapUpdater::purge_confirmations(Map& map) {
  if (confirm_.size() > map.points.size() + 1024) {
    for (auto it = confirm_.begin(); it != confirm_.end();) {
      const MapPoint* p = map.point(it->first);
      it = p != nullptr && p->valid ? std::next(it) : confirm_.erase(it);
    }
  }
}

// Step 5, Sec. 4's 90% rule (Map::redundancy, the mapper's culling rule) on the checked
// keyframes (triggered_): a keyframe whose invalid points plus points shared with >= 3 other
// keyframes exceed redundant_fraction of its points is marked invalid; the mapper replaces it.
void MapUpdater::apply_keyframe_rule(Map& map, MapUpdateStats& st) {
  for (int kid : triggered_) {
    Keyframe* kf = map.keyframe(kid);
    if (kf == nullptr || kf->fixed || !kf->valid) continue;
    if (map.redundancy(*kf).exceeds(redundant_fraction_)) {
      kf->valid = false;
      ++st.keyframes_invalidated;
    }
  }
}

// Step 6: the unmatched duplicates marked by apply_verdict (prune_unmatched) are erased.
void MapUpdater::erase_pruned(Map& map, MapUpdateStats& st) {
  for (int64_t id : prune_) {
    map.erase_point(id);
    confirm_.erase(id);
    ++st.points_pruned;
  }
}

}  // namespace rdslam
