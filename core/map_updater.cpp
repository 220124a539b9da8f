#include "core/map_updater.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rdslam {

namespace {
// Histograms sample every 4th pixel in x and y: the trigger is a global statistic, 1/16 of
// the pixels is plenty and keeps the per-frame cost small.
constexpr int kHistogramStride = 4;
// phi(x') is capped: Alg. 1 needs only whether a nearer point exists and where it projects.
constexpr int kMaxNeighbours = 64;
constexpr int kMaxSelected = 20;  // ChangeDetectionParams::closest_keyframes upper bound
}  // namespace

MapUpdater::MapUpdater(const ChangeDetectionParams& params, const PinholeIntrinsics& K)
    : params_(params), K_(K) {
  cell_px_ = std::max(params_.r1, 4.0);
  selected_.resize(kMaxSelected);
  neighbours_.resize(kMaxNeighbours);
}

const ColorHistogram& MapUpdater::keyframe_histogram(const Keyframe& kf) {
  auto it = kf_hist_.find(kf.id);
  if (it != kf_hist_.end()) return it->second;
  ColorHistogram& h = kf_hist_[kf.id];
  compute_color_histogram(kf.image, kHistogramStride, h);
  return h;
}

void MapUpdater::build_grid(int width, int height) {
  grid_cols_ = std::max(1, static_cast<int>(std::ceil(width / cell_px_)));
  grid_rows_ = std::max(1, static_cast<int>(std::ceil(height / cell_px_)));
  const size_t cells = size_t(grid_cols_) * grid_rows_;
  cell_start_.assign(cells + 1, 0);
  cell_fill_.assign(cells, 0);
  cell_items_.resize(tracked_.size());
  auto cell_of = [&](const Eigen::Vector2d& px) {
    const int cx = std::clamp(static_cast<int>(px.x() / cell_px_), 0, grid_cols_ - 1);
    const int cy = std::clamp(static_cast<int>(px.y() / cell_px_), 0, grid_rows_ - 1);
    return cy * grid_cols_ + cx;
  };
  for (const Tracked& t : tracked_) ++cell_start_[cell_of(t.pixel) + 1];
  for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  for (size_t i = 0; i < tracked_.size(); ++i) {
    const int c = cell_of(tracked_[i].pixel);
    cell_items_[cell_start_[c] + cell_fill_[c]++] = static_cast<int>(i);
  }
}

int MapUpdater::gather_neighbours(const Eigen::Vector2d& x_prime, const Keyframe* first_kf) {
  const double r1_2 = params_.r1 * params_.r1;
  const int x0 = std::max(0, static_cast<int>((x_prime.x() - params_.r1) / cell_px_));
  const int x1 = std::min(grid_cols_ - 1, static_cast<int>((x_prime.x() + params_.r1) / cell_px_));
  const int y0 = std::max(0, static_cast<int>((x_prime.y() - params_.r1) / cell_px_));
  const int y1 = std::min(grid_rows_ - 1, static_cast<int>((x_prime.y() + params_.r1) / cell_px_));
  int n = 0;
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const int c = cy * grid_cols_ + cx;
      for (int k = cell_start_[c]; k < cell_start_[c + 1] && n < kMaxNeighbours; ++k) {
        const Tracked& t = tracked_[cell_items_[k]];
        if ((t.pixel - x_prime).squaredNorm() > r1_2) continue;
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
      }
    }
  }
  return n;
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

MapUpdateStats MapUpdater::update(Map& map, const cv::Mat& image, const Pose& T_cam_world,
                                  const Features& features, const std::vector<int64_t>& point_of,
                                  std::vector<int64_t>* invalidated) {
  MapUpdateStats st;
  if (!params_.map_update || image.empty() || map.keyframes.empty()) return st;

  // Candidate keyframes: valid ones with an image.
  kf_ids_.clear();
  z_axes_.clear();
  centres_.clear();
  for (auto& kv : map.keyframes) {
    const Keyframe& kf = kv.second;
    if (!kf.valid || kf.image.empty() || kf.image.channels() != image.channels()) continue;
    kf_ids_.push_back(kf.id);
    z_axes_.push_back(kf.T_cam_world.R.row(2).transpose());  // camera Z axis in world
    centres_.push_back(kf.T_cam_world.centre());
  }
  // Histogram cache entries of erased keyframes are dropped (bounded by max_keyframes).
  for (auto it = kf_hist_.begin(); it != kf_hist_.end();) {
    it = map.keyframes.count(it->first) ? std::next(it) : kf_hist_.erase(it);
  }
  const Eigen::Vector3d cur_z = T_cam_world.R.row(2).transpose();
  const Eigen::Vector3d cur_c = T_cam_world.centre();
  const int nsel = select_closest_keyframes(
      cur_z, cur_c, z_axes_.data(), centres_.data(), static_cast<int>(kf_ids_.size()),
      params_.keyframe_view_angle_deg, params_.closest_keyframes, selected_.data(), kMaxSelected);
  st.keyframes_selected = nsel;
  if (nsel == 0) return st;

  compute_color_histogram(image, kHistogramStride, current_hist_);
  if (!current_hist_.valid) return st;

  // Tracked points of this frame: phi(x') candidates, and the set Alg. 1 skips.
  tracked_.clear();
  tracked_ids_sorted_.clear();
  const int nf = std::min<int>(features.count, static_cast<int>(point_of.size()));
  for (int i = 0; i < nf; ++i) {
    if (point_of[i] < 0) continue;
    const MapPoint* p = map.point(point_of[i]);
    if (p == nullptr) continue;
    const Eigen::Vector3d pc = T_cam_world * p->p_world;
    if (pc.z() <= 1e-9) continue;
    Tracked t;
    t.pixel = Eigen::Vector2d(features.un[i].x, features.un[i].y);
    t.p_world = p->p_world;
    t.depth = pc.z();
    t.id = p->id;
    tracked_.push_back(t);
    tracked_ids_sorted_.push_back(p->id);
  }
  std::sort(tracked_ids_sorted_.begin(), tracked_ids_sorted_.end());
  build_grid(image.cols, image.rows);

  const int h = params_.window / 2;
  for (int s = 0; s < nsel; ++s) {
    Keyframe* kf = map.keyframe(kf_ids_[selected_[s]]);
    if (kf == nullptr) continue;
    const ColorHistogram& kh = keyframe_histogram(*kf);
    if (!kh.valid || histogram_difference(kh, current_hist_) <= params_.histogram_threshold) {
      continue;
    }
    ++st.keyframes_triggered;
    const Eigen::Vector3d kf_c = kf->T_cam_world.centre();
    const int kn = std::min<int>(kf->features.count, static_cast<int>(kf->point_of.size()));
    for (int i = 0; i < kn; ++i) {
      const int64_t pid = kf->point_of[i];
      if (pid < 0) continue;
      MapPoint* p = map.point(pid);
      if (p == nullptr || !p->valid) continue;
      if (std::binary_search(tracked_ids_sorted_.begin(), tracked_ids_sorted_.end(), pid)) {
        continue;  // observed in this frame: present
      }
      const Eigen::Vector3d pc = T_cam_world * p->p_world;
      if (pc.z() <= 1e-9) continue;
      const Eigen::Vector2d xp = K_.project(pc);
      if (xp.x() < h || xp.y() < h || xp.x() >= image.cols - h || xp.y() >= image.rows - h) {
        continue;  // not in the current view
      }
      const Eigen::Vector3d pk = kf->T_cam_world * p->p_world;
      if (pk.z() <= 1e-9) continue;
      const Eigen::Vector3d n_x = (kf_c - p->p_world).normalized();
      const Eigen::Vector3d n_xp = (cur_c - p->p_world).normalized();
      double d_c = std::numeric_limits<double>::infinity();
      // Eq. (2) only when the view test lets Alg. 1 reach it (it is the expensive part).
      if (n_x.dot(n_xp) >= params_.tau_n) {
        const cv::Point2f& kp = kf->features.kps[i].pt;
        d_c = appearance_difference(kf->image, Eigen::Vector2d(kp.x, kp.y), image, xp,
                                    pk.z() / pc.z(), params_.window, params_.search_d);
      }
      const Keyframe* first = first_keyframe(map, *p);
      Eigen::Vector2d x_first(-1e9, -1e9);
      if (first != nullptr) {
        const Eigen::Vector3d pf = first->T_cam_world * p->p_world;
        if (pf.z() > 1e-9) x_first = K_.project(pf);
      }
      int nn = 0;
      if (std::isfinite(d_c) && d_c > params_.tau_c && params_.occlusion_handling) {
        nn = gather_neighbours(xp, first);
      }
      const PointDecision d =
          update_point_validity(params_, n_x, n_xp, d_c, pc.z(), x_first, neighbours_.data(), nn);
      ++st.points_checked;
      ++st.decisions[static_cast<int>(d)];
      if (is_invalidation(d)) {
        p->valid = false;
        ++st.points_invalidated;
        if (invalidated != nullptr) invalidated->push_back(pid);
      }
    }
    // Sec. 4's 90% rule on the checked keyframe.
    int invalid = 0, shared = 0, total = 0;
    for (int i = 0; i < kn; ++i) {
      const MapPoint* p = kf->point_of[i] >= 0 ? map.point(kf->point_of[i]) : nullptr;
      if (p == nullptr) continue;
      ++total;
      if (!p->valid) {
        ++invalid;
      } else if (p->obs.size() >= 4) {
        ++shared;
      }
    }
    if (!kf->fixed && keyframe_is_invalid(invalid, shared, total, params_.keyframe_invalid_ratio)) {
      kf->valid = false;
      ++st.keyframes_invalidated;
    }
  }
  return st;
}

}  // namespace rdslam
