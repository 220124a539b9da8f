// Online 3D point and keyframe updating of RDSLAM Section 4 (Algorithm 1) applied to the map.
//
// Input: one tracked frame (UpdateFrame: image, pose, the tracked features' pixels and map ids,
// the ids PARSAC rejected). The mapper calls it for every keyframe candidate and for the
// tracker's frame observations (every dynamic.check_every_n_frames tracked frames,
// core/keyframe.h). Per call, update() runs these steps (private members, in this order:
// moved_events, select_keyframes, collect_tracked, gather_candidates, judge_candidates,
// purge_confirmations, apply_keyframe_rule, erase_pruned):
//  1. select_keyframes: the `closest_keyframes` valid keyframes (optical axis within
//     `keyframe_view_angle_deg`, nearest camera centres); a keyframe is checked (triggers) when
//     its colour histogram differs from the frame's by more than `histogram_threshold`
//     (default 0: always, see below);
//  2. gather_candidates: the checked keyframes' valid points that are not tracked in this
//     frame, project into the view (untracked_in_view), are observed by >= `min_observations`
//     keyframes and reproject onto the keyframe's feature (chi2 95%); eq. (2) against each such
//     keyframe passing the view test (add_candidate; gather_unselected with
//     `check_all_in_view`);
//  3. judge_candidates: per point, in id order, judge runs Algorithm 1 once on its best
//     reference (smallest D_c); before a point is called changed, eq. (2) is also searched
//     along the reference keyframe's ray over the point's depth uncertainty (`ray_search`), and
//     the recent checked frames tell what replaced it (`temporal_check`, new_surface: moving,
//     static in front, static at/behind); with `require_static_evidence` only "static
//     at/behind" lets a verdict invalidate; apply_verdict then applies it at once: a change
//     verdict must repeat in `confirm_checks` consecutive checks before V(X) = 0;
//  4. the second paper's counters (`landmark_counters`): a tracked point is "still" (counts
//     reset; collect_tracked), a PARSAC-rejected point (or, with `flow_rejection` and a
//     stationary camera, a tracked point on dense optical flow) is "moved" (moved_events, at
//     the start of the call), Alg. 1's "occluded by an untracked, i.e. moving, object" verdict
//     is "missed" (apply_verdict); above moved_threshold / miss_threshold the point is
//     discarded (V(X) = 0);
//  5. apply_keyframe_rule: the 90% rule on every checked keyframe;
//  6. with `prune_unmatched`, points in view and unchanged (D_c <= tau_c) that are not tracked
//     while a tracked feature lies within 3 px of their projection (duplicates of a point the
//     tracker uses), in more than `miss_threshold` consecutive checks, are marked by
//     apply_verdict and erased from the map by erase_pruned (MapUpdateStats::points_pruned;
//     the second paper's miss counter).
// The steps share the call's state through MapUpdater::Call (on update()'s stack) and the
// scratch members; the frame joins the recent frames (remember) when the call ends.
// Invalid points leave the matching index at the mapper's next publish (core/mapper.cpp skips
// !valid; an observation that invalidated points publishes at once); invalid keyframes are
// removed by the mapper. With `map_update = false` update() changes nothing (Figure 9
// ablation; it only keeps the frame for recent_frames_agree when check_new_points is on);
// with `occlusion_handling = false` Alg. 1 invalidates on appearance alone (Figures 4-5).
//
// Deviations from the paper (argued where the parameters are declared, core/change_detection.h,
// and in docs/slam.md "Map updating"): histogram trigger default 0, normalised eq. (2),
// established points only, best reference per point, ray search, the temporal check and the
// evidence it supplies to Alg. 1, confirmation of change verdicts, the
// miss counter restricted to Alg. 1's undecidable case (a plain "not matched" count would
// discard every point occluded for a few frames, against Alg. 1's purpose).
//
// The 90% rule is one rule with one key (mapper.redundant_fraction): Map::redundancy counts
// invalid points and points observed by at least 3 other keyframes; the mapper culls covisible
// keyframes of a new keyframe by it, and this step marks checked keyframes invalid by it.
//
// Pixels: the map stores ideal (undistorted) feature coordinates and raw images. Geometry
// (Algorithm 1's phi(x'), the first-keyframe test, rays, reprojection gates) runs on ideal
// pixels; every eq. (2) window is taken in the raw images through the camera model
// (core/camera.h): at the raw keypoint in a keyframe and at the distorted projection
// (CameraModel::project) of X in the current or a recent frame, the window's pixel grid
// mapped by the lens's local linear stretch at both ends (window_difference: warp
// scale J' J^-1, J = CameraModel::distort_jacobian). "In view" means the raw window lies
// inside the image. Without distortion raw and ideal pixels are the same and the warp is the
// depth ratio alone.
//
// params() returns the parameters in use: with normalise_appearance, tau_c holds
// tau_c_relative (the threshold of the normalised score).
//
// Ownership: the caller (the mapper) owns the Map and passes it in; the updater owns only its
// scratch buffers, the per-keyframe histogram cache, the confirmation counts, copies of the
// last kHistory checked frames (temporal check) and the previous observation's grey image
// (flow). Threads: one thread (the mapper's). Allocation: buffers
// grow during warm-up and are reused; the histogram cache allocates once per new keyframe.
#pragma once

#include <Eigen/StdVector>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "core/camera.h"
#include "core/change_detection.h"
#include "core/features.h"
#include "core/geometry.h"
#include "core/map.h"

namespace rdslam {

// One tracked frame as the updater sees it: pose, image, the tracked features (undistorted
// pixels and map point ids, -1 = untracked, skipped) and the ids the robust estimator rejected
// in this frame. frame_no (the tracker's tracked-frame counter, -1 unknown) lets the optional
// optical-flow test know how many frames separate two observations.
struct UpdateFrame {
  const cv::Mat* image = nullptr;
  Pose T_cam_world;
  const cv::Point2f* un = nullptr;
  const int64_t* point_of = nullptr;
  int count = 0;
  const int64_t* rejected = nullptr;
  int rejected_count = 0;
  int64_t frame_no = -1;
  int64_t stamp_ns = -1;  // capture time (temporal check; -1 unknown)
};

struct MapUpdateStats {
  int keyframes_selected = 0;      // closest keyframes found
  int keyframes_triggered = 0;     // of those, histogram difference above the threshold
  int points_checked = 0;          // points run through Algorithm 1
  int points_invalidated = 0;      // V(X) set to 0 in this call
  int keyframes_invalidated = 0;   // keyframes newly marked invalid in this call
  int decisions[10] = {};          // per PointDecision value
  int points_not_established = 0;  // skipped: fewer than min_observations
  int points_inconsistent = 0;     // skipped: X does not reproject onto the keyframe's feature
  int points_unselected = 0;       // in view, held by no selected keyframe (check_all_in_view)
  int counter_discards = 0;        // of points_invalidated: by the counters
  int flow_moved = 0;              // tracked points on flowing regions
  int points_pruned = 0;           // erased: unmatched duplicates (prune_unmatched)
  bool flow_computed = false;      // camera stationary: flow ran this frame
  // The call changed what the tracker's matching index must hold (the mapper publishes).
  bool map_changed() const {
    return points_invalidated > 0 || keyframes_invalidated > 0 || points_pruned > 0;
  }
};

// Why a point was invalidated (tests and diagnostics): an Algorithm 1 decision or a counter.
enum class InvalidationCause : uint8_t {
  kNothingInFront = 0,   // Alg. 1: all neighbours at or behind X
  kSameObject,           // Alg. 1: a nearer neighbour close to X in its first keyframe
  kNoOcclusionHandling,  // ablation: appearance alone
  kMovedRejected,        // counter: rejected by the robust estimator moved_threshold times
  kMovedFlow,            // counter: matched on a flowing region while stationary
  kMissed,               // counter: "occluded by a moving object" for miss_threshold checks
  kStaticChange,         // Alg. 1 + temporal check: nothing tracked near, new appearance static
};
const char* to_string(InvalidationCause c);
struct InvalidationRecord {
  int64_t id = -1;
  InvalidationCause cause = InvalidationCause::kNothingInFront;
  double d_c = 0.0;   // eq. (2) value (Alg. 1 causes)
  int keyframe = -1;  // keyframe whose point list contained X (Alg. 1 causes)
};

// One Algorithm 1 verdict (diagnostics: MapUpdater::set_check_log).
struct CheckRecord {
  int64_t id = -1;
  PointDecision decision = PointDecision::kKeepNotChecked;
  NewSurface seen = NewSurface::kUnknown;
  float d_c = 0.f;         // eq. (2) after the ray search
  int neighbours = 0;      // |phi(x')|
  float depth = 0.f;       // z_X in the current camera
  float depth_seen = 0.f;  // temporal check: depth of what x' shows (0: none found)
  float u = 0.f, v = 0.f;  // x', X's projection into the current frame
};

class MapUpdater {
 public:
  // Diagnostics: every Algorithm 1 verdict is appended to `log` (nullptr: off, the default;
  // appending allocates, so tests and tools only).
  void set_check_log(std::vector<CheckRecord>* log) { check_log_ = log; }
  // `redundant_fraction` is the keyframe-redundancy fraction of Sec. 4's 90% rule
  // (mapper.redundant_fraction, Map::redundancy), shared with the mapper's keyframe culling.
  MapUpdater(const ChangeDetectionParams& params, const CameraModel& camera,
             double redundant_fraction = 0.9);
  // An undistorted camera of these intrinsics (tests).
  MapUpdater(const ChangeDetectionParams& params, const PinholeIntrinsics& K,
             double redundant_fraction = 0.9);

  // One frame: `image` is the frame (same channel count as the keyframe images), T_cam_world
  // its estimated pose, `features`/`point_of` the frame's features and, per feature, the
  // tracked map point id or -1. `invalidated` (optional) receives the ids set invalid.
  MapUpdateStats update(Map& map, const cv::Mat& image, const Pose& T_cam_world,
                        const Features& features, const std::vector<int64_t>& point_of,
                        std::vector<int64_t>* invalidated = nullptr);
  // The general form (frame observations of the tracker, core/keyframe.h). `records`
  // (optional) receives one entry per point invalidated, with the cause.
  MapUpdateStats update(Map& map, const UpdateFrame& frame,
                        std::vector<int64_t>* invalidated = nullptr,
                        std::vector<InvalidationRecord>* records = nullptr);

  // dynamic.check_new_points, for the mapper creating a point at p_world from a keyframe whose
  // feature is at raw pixel `x` (`depth` in that keyframe, `image` the keyframe's frame, `stamp_ns`
  // its time): false when the oldest recent checked frame (widest baseline) shows a different
  // window at the point's projection (eq. (2) above tau_c); true when it agrees or cannot
  // decide. Mapper thread.
  bool recent_frames_agree(const Eigen::Vector3d& p_world, const cv::Mat& image,
                           const Eigen::Vector2d& x, double depth, int64_t stamp_ns) const;
  const ChangeDetectionParams& params() const { return params_; }
  // Forgets per-map state (confirmation counts, histograms, the previous frame): the mapper
  // calls it when the map is reset.
  void reset();

 private:
  struct Tracked {
    Eigen::Vector2d pixel;
    Eigen::Vector3d p_world;
    double depth = 0.0;
    int64_t id = -1;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  // A pixel in both forms: ideal (geometry) and raw (where the image shows it).
  struct Pixel {
    Eigen::Vector2d ideal{0, 0}, raw{0, 0};
  };
  Pixel pixel(const Eigen::Vector3d& p_cam) const;  // projection of a point in front
  Pixel pixel_of_ideal(const Eigen::Vector2d& ideal) const;
  // Eq. (2) (ChangeDetectionParams window, normalisation) between the window at `a` in
  // image_a and the one at `b` in image_b, `scale` = depth in a / depth in b; raw pixels,
  // the grid warped by the lens's local stretch at both ends.
  double window_difference(const cv::Mat& image_a, const Pixel& a, const cv::Mat& image_b,
                           const Pixel& b, double scale, int search_d,
                           double accept = -std::numeric_limits<double>::infinity()) const;
  const ColorHistogram& keyframe_histogram(const Keyframe& kf);
  void build_grid(int width, int height);
  int gather_neighbours(const Eigen::Vector2d& x_prime, const Keyframe* first_kf);
  const Keyframe* first_keyframe(Map& map, const MapPoint& p) const;
  // Calls f(const Tracked&) for each tracked_ point within `radius` px of x (grid of
  // build_grid) until f returns false.
  template <class F>
  void for_each_tracked_within(const Eigen::Vector2d& x, double radius, F&& f) const;
  bool tracked_within(const Eigen::Vector2d& x, double radius) const;  // any tracked_ pixel
  // Eq. (2) searched along the keyframe's ray through X's feature over X's depth uncertainty
  // (ChangeDetectionParams::ray_search); the smallest D_c found (+inf: not computable).
  double ray_difference(Map& map, const MapPoint& p, const Keyframe& kf, int feat,
                        const cv::Mat& image, const Pose& T_cam_world) const;
  bool counter_event(Map& map, int64_t id, LandmarkEvent e);
  void flow_events(Map& map, const UpdateFrame& f, MapUpdateStats& st,
                   std::vector<int64_t>* invalidated);
  void invalidate(MapPoint& p, MapUpdateStats& st, std::vector<int64_t>* invalidated,
                  InvalidationCause cause, double d_c = 0.0, int kf = -1);

  ChangeDetectionParams params_;
  CameraModel camera_;
  bool lens_ = false;  // camera_ has distortion
  PinholeIntrinsics K_;
  // Ideal-pixel box the tracked-point grid covers: the image, or with a lens, the ideal
  // pixels of the image's border (x0, y0, x1, y1).
  double ideal_box_[4] = {0, 0, 0, 0};
  double redundant_fraction_ = 0.9;
  ColorHistogram current_hist_;
  std::unordered_map<int, ColorHistogram> kf_hist_;
  // Scratch (reused every frame).
  std::vector<int> kf_ids_;
  std::vector<Eigen::Vector3d> z_axes_, centres_;
  std::vector<int> selected_;
  std::vector<Tracked, Eigen::aligned_allocator<Tracked>> tracked_;
  std::vector<int64_t> tracked_ids_sorted_;
  std::vector<int> cell_start_, cell_items_, cell_fill_;
  int grid_cols_ = 0, grid_rows_ = 0;
  double cell_px_ = 20.0;
  std::vector<NeighbourPoint, Eigen::aligned_allocator<NeighbourPoint>> neighbours_;
  struct Candidate {
    int64_t id = -1;
    int kf = -1, feat = -1;
    Eigen::Vector3d n_x, n_xp;
    Pixel xp;  // x'
    double depth = 0.0, d_c = 0.0;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  std::vector<Candidate, Eigen::aligned_allocator<Candidate>> candidates_;
  std::vector<int> triggered_;
  std::vector<int64_t> covered_;  // ids of the selected keyframes' candidates (sorted)
  std::vector<int64_t> prune_;    // points to erase at the end of the call (prune_unmatched)
  // Consecutive change verdicts per point (confirm_checks); entries of points that became
  // invalid or were erased are purged when the table outgrows the map.
  std::unordered_map<int64_t, int> confirm_;
  // Temporal check (dynamic.temporal_check): the last kHistory checked frames (images copied
  // into buffers reused after warm-up), newest at history_[(history_head_ - 1) mod kHistory].
  static constexpr int kHistory = 6;
  struct Recent {
    cv::Mat image;
    Pose T_cam_world;
    int64_t stamp_ns = -1;
  };
  // A recent frame older than stamp_ns (by at most temporal_max_gap_s) of image's size/type.
  bool usable(const Recent& r, const cv::Mat& image, int64_t stamp_ns) const;
  // new_surface's second and third views: the usable recent frame with the widest baseline,
  // and the one whose baseline is nearest half of it (best_b).
  const Recent* widest_recent(const cv::Mat& image, int64_t stamp_ns, const Eigen::Vector3d& c_cur,
                              double* baseline) const;
  const Recent* mid_recent(const cv::Mat& image, int64_t stamp_ns, const Eigen::Vector3d& c_cur,
                           const Recent* wide, double best_b) const;
  NewSurface new_surface(const Eigen::Vector3d& p_world, const Pixel& x_prime, double depth,
                         const cv::Mat& image, const Pose& T_cam_world, int64_t stamp_ns,
                         double* depth_seen = nullptr) const;
  void remember(const UpdateFrame& f);
  Recent history_[kHistory];
  int history_head_ = 0;
  // Optical flow (dynamic.flow_rejection): the previous observation.
  cv::Mat prev_gray_, cur_gray_, flow_;
  Pose prev_T_;
  int64_t prev_frame_no_ = -1;
  std::vector<float> fx_, fy_;
  std::vector<uint8_t> keep_;
  std::vector<InvalidationRecord>* records_ = nullptr;  // of the update() call in progress
  std::vector<CheckRecord>* check_log_ = nullptr;

  // The steps of update() (numbered as in the comment at the top of this file) and the state
  // of the call they share: the frame, its camera's optical axis and centre in the world, the
  // statistics and invalidated ids being filled. Lives on update()'s stack.
  struct Call {
    Map& map;
    const UpdateFrame& frame;
    const cv::Mat& image;     // *frame.image
    const Pose& T_cam_world;  // frame.T_cam_world
    Eigen::Vector3d cur_z, cur_c;
    MapUpdateStats& st;
    std::vector<int64_t>* invalidated;
  };
  void moved_events(Call& c);     // 4: rejected / on flow -> "moved"
  int select_keyframes(Call& c);  // 1
  void collect_tracked(Call& c);  // phi(x')'s candidates; 4: tracked -> "still"
  // 2: candidates_ and triggered_ from the selected (and, with check_all_in_view, other)
  // keyframes.
  void gather_candidates(Call& c, int nsel);
  void gather_unselected(Call& c);
  bool triggers(const Keyframe& kf);
  bool untracked_in_view(const Call& c, const MapPoint& p, Eigen::Vector3d& pc, Pixel& xp) const;
  void add_candidate(Call& c, const Keyframe& kf, int i, const MapPoint& p,
                     const Eigen::Vector3d& pc, const Pixel& xp);
  // 3: per candidate point, judge (Algorithm 1) then apply_verdict (confirmation, V(X) = 0,
  // the counters' "still"/"missed", marking for 6).
  void judge_candidates(Call& c);
  PointDecision judge(Call& c, const Candidate& cand, const MapPoint& p, double& d_c);
  void apply_verdict(Call& c, const Candidate& cand, MapPoint& p, PointDecision d, double d_c);
  void purge_confirmations(Map& map);
  void apply_keyframe_rule(Map& map, MapUpdateStats& st);  // 5
  void erase_pruned(Map& map, MapUpdateStats& st);         // 6
};

}  // namespace rdslam
