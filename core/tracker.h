// The tracker (Sec. 3): per frame, features are extracted and matched to the reference
// features (3D points), the camera pose is estimated robustly and refined by eq. (1) (then
// checked for a coherently displaced image region, TrackerParams::submotion_chi2), and the
// frame is proposed as a keyframe by the paper's rules (Sec. 4).
//
// State machine (published with every pose):
//   INITIALIZING --two-view init--> TRACKING --too few inliers--> LOST
//   LOST --relocalization against the map--> RELOCALIZED (one frame) --> TRACKING
//   LOST for `reset_after_lost_frames` with a map of at most 2 keyframes, or for
//   `new_map_after_s` seconds (frame stamps) with any map --> INITIALIZING a new map epoch
//   (recovery, docs/slam.md: the mapper keeps a map of more than 2 keyframes frozen; while LOST
//   or INITIALIZING, relocalization also searches the kept earlier maps and, when it succeeds
//   in one, the tracker continues in that map's epoch; when the mapper merges the current map
//   into an earlier one, follow_merge() moves the tracker's state into the earlier map's frame)
// A pose is published as TRACKING/RELOCALIZED only when at least `min_inliers` 2D-3D matches
// support it after refinement.
//
// track() runs these steps (private members, in this order), then fills the TrackResult once:
//   extract                  features of the frame; the newest map snapshot
//   track_initializing       INITIALIZING: two-view initialization (core/initializer.h); the
//                            first attempt at fast motion switches the run to the deeper
//                            pyramid (TrackerParams::fast_motion_levels) and is repeated on it
//   TRACKING / RELOCALIZED, a cascade around the constant-velocity prediction (predict_pose:
//   the last motion, scaled by the frames' stamp intervals when frames were dropped), each search
//   tried while the previous one left fewer than `search_min_inliers` inliers (a search
//   estimates a pose only from at least `search_min_matches` matches):
//     track_with_motion_model  previous frame's points in `motion_search_px`; robust pose
//                              (`robust_per_frame`; a consensus below `robust_min_inliers` is
//                              no model: eq. (1) from the prediction) and eq. (1)
//     widened_motion_search    the same in twice the radius, eq. (1) only
//     local_map_fallback       (with a map) the map's points in 4 x `local_search_px`, eq. (1)
//     extend_with_local_map    with at least `extend_min_inliers`: every visible map point in
//                              `local_search_px`, eq. (1), then submotion_test
//     update_state             TRACKING (>= `min_inliers`, new velocity) or LOST
//   handle_lost              LOST: relocalize() (place recognition, then at least
//                            `reloc_min_matches` matches with the candidates' points,
//                            `robust_min_inliers` robust inliers, `reloc_min_inliers` after
//                            refinement) or, lost too long with a tiny map, reset_map()
//   track_rotation_only      (TrackerParams::rotation_only) when track_with_map found no pose
//                            while the camera was turning on the spot, or while it keeps doing
//                            so: the rotation with the centre held (below)
//   a found pose is then proposed as a keyframe / observation (not the initialization frame,
//   which start_from_init sends itself; not a rotation-only pose; nothing while
//   SlamLink::localize_only freezes the map) and becomes the previous frame.
// A prior map (start_with_map) starts the tracker LOST (new_map_after_s counts from the first
// frame; a frozen map, SlamLink::localize_only, is never replaced); SlamLink::reset_requests
// makes it start a new map at the next frame (reset_map).
//
// Rotation-only tracking (issue 23 item 3; after Pirchheim et al., "Handling pure camera
// rotation in keyframe-based SLAM", ISMAR 2013): a robot turning on the spot rotates out of its
// map, and without translation no new point can be triangulated. When track_with_map fails
// and the recent motion (smoothed over about 5 frames) was a rotation of at least
// `rotation_min_deg` per frame whose translation, over the median depth of the last frame's
// points, is below `rotation_max_parallax_ratio` times that angle, the tracker enters rotation
// mode: the last
// tracked frame becomes a rotation-only keyframe (its features kept with their world bearing
// vectors: points at infinity seen from the held centre), and each frame's rotation is
// estimated, with the centre held, from the visible map points (as directions from the centre)
// and the rotation keyframe's bearings matched by descriptor around their predicted pixels
// (2-point Kabsch consensus, then eq. (1) over the rotation: core/pose_refine.h). When its
// matches fall below `rotation_refresh_ratio` of those it had on its first frame and the view
// has turned by at least 5 degrees since it, the current frame becomes the next rotation
// keyframe (matches lost to translation make none: a camera that drives off in rotation mode
// runs out of inliers and goes LOST, to relocalize, rather than keep a wrong centre); so does
// a frame after the turn has slowed below half of `rotation_min_deg` per frame. Each frame first
// tries the full track_with_map; its pose (enough map inliers: the map is in view again) ends
// rotation mode when its centre lies within `rotation_exit_max_shift` times its inliers' median
// depth of the held centre (a full pose farther away matched a repeated texture; the frame stays
// rotation-only). Rotation-only keyframes and their points at infinity stay inside the tracker:
// they are not sent to the mapper (no keyframe candidates, no frame observations while in rotation
// mode), so bundle adjustment, map updating (change detection) and PARSAC never see them. Not done
// yet: a turn into unmapped space followed by translation there (delayed triangulation of the
// rotation keyframes' features) goes LOST as before.
//
// Matching (fast mode): projection-guided. The previous frame's tracked points are projected
// with a constant-velocity prediction and matched in a radius (descriptor distance + ratio);
// then every visible point of the active matching index (core/match_index.h) is projected
// with the refined pose and matched in a small radius at its predicted pyramid level. SIFT
// mode uses the same projection-guided search with L2 distances and the paper's ratio 0.6,
// and the index's FLANN KD-tree for relocalization (global matching, Sec. 3).
//
// Keyframe rule (Sec. 4): a frame whose pose was found is a potential keyframe when it shares
// fewer than m1 tracked points with its reference keyframe (the keyframe sharing most), or
// when it tracks fewer than `keyframe_overlap_ratio` times the reference keyframe's
// well-observed points (ORB-SLAM's monocular rule, 0.9: ORB features are denser than the
// paper's SIFT, so the absolute m1 = 80 alone reacts too late), or after
// `max_keyframe_interval` frames (`young_map_keyframe_interval` while the map has fewer than
// `young_map_keyframes` keyframes: the young map's scale and depths rest on the two-view
// initialization's short baseline until later keyframes refine them). The mapper then accepts it
// only if it contributes more than m2 new points (condition 3).
//
// Ownership: Tracker owns all its buffers (sized at construction from the params) and holds
// the active MapSnapshot. Threads: tracker thread only. No heap allocation per frame after
// warm-up, except while INITIALIZING (OpenCV model fitting) and, in SIFT mode (FLANN) or
// without a vocabulary, relocalizing.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/debug_frame.h"
#include "core/features.h"
#include "core/frame_source.h"
#include "core/initializer.h"
#include "core/keyframe.h"
#include "core/params.h"
#include "core/pose_estimation.h"
#include "core/relocalizer.h"
#include "core/stages.h"

namespace rdslam {

struct TrackerParams {
  int min_inliers = 30;            // fewer: LOST
  int reloc_min_inliers = 40;      // relocalization accepted with at least this many
  double motion_search_px = 15.0;  // radius of the motion-model search (level-0 pixels)
  double local_search_px = 4.0;    // radius of the map-point projection search
  // The search cascade of Tracker::track() (see the header comment) and relocalization.
  int search_min_matches = 15;  // matches a search needs before a pose is estimated from them
  int search_min_inliers = 15;  // fewer inliers from a search: the next search is tried
  int extend_min_inliers = 10;  // inliers needed to extend the pose with the local map
  int robust_min_inliers = 10;  // a robust estimate with fewer inliers is no model
  int reloc_min_matches = 10;   // global matches needed to attempt relocalization
  // Place recognition for relocalization (ORB, core/relocalizer.h): keyframes matched per LOST
  // frame, vocabulary level of the direct index, and the vocabulary file ("" = the built-in
  // data/vocab/orb_k10l4.bin, default_vocabulary_path()).
  int reloc_candidates = 3;
  int reloc_node_level = 2;
  std::string reloc_vocabulary;
  int m1 = 80;                          // paper Sec. 4: fewer common features -> potential keyframe
  double keyframe_overlap_ratio = 0.9;  // or tracking fewer than this x reference's points
  int max_keyframe_interval = 20;       // frames; then propose a keyframe anyway
  int young_map_keyframes = 12;         // below this many keyframes the map is young
  int young_map_keyframe_interval = 5;  // max_keyframe_interval while the map is young
  int reset_after_lost_frames = 15;     // with a tiny map: back to INITIALIZING
  // Recovery: LOST this long (seconds of frame stamps since the first LOST frame, whatever the
  // map's size) starts a new map epoch; 0 = never (only the tiny-map rule above).
  double new_map_after_s = 1.0;
  // Time-aware constant velocity: the last motion spans the stamp interval between the last
  // two tracked frames; the prediction for a frame dt after the last tracked one applies it
  // scaled by dt / that interval (so a live pipeline that dropped frames predicts the whole
  // gap), clamped to [1 / prediction_max_scale, prediction_max_scale]. Stamps that do not
  // increase fall back to one motion per frame.
  double prediction_max_scale = 4.0;
  // Lossless replay only: after proposing a keyframe, wait for the mapper to finish it, so a
  // replay faster than real time maps like an offline run. Off for live cameras: then the
  // mapper never blocks the tracker for more than the index pointer swap.
  bool sync_mapper = false;
  // Sec. 3/5: robust pose (PARSAC, `parsac.method`) on the frame's 2D-3D matches before the
  // eq. (1) refinement; false: refinement from the motion-model prediction only.
  bool robust_per_frame = true;
  // Coherent sub-motion test after the final eq. (1) (not in the paper). An object that starts
  // moving rigidly (Figure 8's book) stays inside the inlier gate for a few frames and pulls the
  // pose along the directions a far background constrains weakly; under that compromise pose
  // neither group's residuals stand out. So the frame's inliers are re-estimated by a second
  // robust estimator (parsac.method) with the tight gate `submotion_gate_px`, whose consensus is
  // the larger, spatially spread rigid motion, and under that pose each PARSAC bin
  // (parsac.bins_x x bins_y) with >= 4 inliers tests its mean normalised residual against zero
  // (squared z-score, chi-square 2 DoF for static points). Bins above `submotion_chi2` with a
  // like-displaced such bin among their 8 neighbours (a moving region, not one bad point) are
  // dropped for this frame and eq. (1) is re-run without them; then the test runs once more
  // under the refit pose. 0 disables.
  double submotion_chi2 = 13.82;  // chi-square 2 DoF, 99.9%
  // 1.5 px keeps about two thirds of the static inliers of a 1-px-per-axis keypoint noise (level
  // 0), so the tight consensus is still the majority motion, while a region displaced by a few
  // pixels falls out of it.
  double submotion_gate_px = 1.5;
  // Rotation-only tracking (see the header comment).
  bool rotation_only = true;
  double rotation_min_deg = 0.5;              // per frame, for entering rotation mode
  double rotation_max_parallax_ratio = 0.25;  // translation / depth below this x the angle
  double rotation_refresh_ratio = 0.5;        // next rotation keyframe below this of its matches
  double rotation_exit_max_shift = 0.12;      // full pose ends it within this x depth of centre
  // Fast motion (ORB): when an initialization attempt sees a median flow of at least
  // `init_fast_flow_frac` of the image width (kitti06 `--every 3`: 4.4%; the other scenes of
  // the replay set start below 2.8%), the features of the rest of the run are extracted on a
  // pyramid of this many levels (ORB-SLAM's KITTI setting, 8 x 1.2), the map being initialized
  // starts again from that frame, and the mapper keeps the new map's points at that many
  // levels. A camera driving forward at a low frame rate sees its points grow by 1.2-1.5x per
  // frame: on 4 levels (scale range 1.73) they leave the pyramid within a frame or two. Not the
  // default pyramid: 8 levels everywhere measured worse on the indoor scenes (docs/slam.md).
  // 0 or at most features.levels: off.
  int fast_motion_levels = 8;
  // Features per frame on that pyramid (0: features.max_features); the tracker's per-frame
  // buffers are sized for the larger of the two at start. 2000 (ORB-SLAM's KITTI setting) makes
  // synth:driving worse on 14 of 16 scene seeds that switch to this pyramid (one over 1%): off
  // by default. kitti06 `--every 3` keeps its map on every PARSAC seed measured without it since
  // matching.orb_local_ratio 0.9 (docs/slam.md, "Fast forward motion: weak tracking", "The
  // projection search's ratio").
  int fast_motion_features = 0;
  InitializerParams init;

  void visit(ParamVisitor& v);
};

struct TrackerStats {
  int matches_motion = 0, matches_local = 0, inliers = 0;
  int candidates_sent = 0;
  InitStatus last_init = InitStatus::kNoReference;
  Pose predicted;  // T_cam_world the motion model predicted for the last frame tracked with a map
  bool rotation_mode = false;  // the last frame's pose is rotation-only (centre held)
  int rotation_frames = 0;     // frames posed rotation-only (since construction)
  int rotation_keyframes = 0;  // rotation-only keyframes made (tracker-local)
  int matches_bearing = 0;     // the last rotation-only frame's bearing inliers
};

class Tracker {
 public:
  Tracker(const TrackerParams& params, const FeatureParams& features,
          const BundleAdjustmentParams& ba, const ParsacParams& parsac, const CameraModel& camera,
          std::shared_ptr<SlamLink> link, int max_points, int max_keyframes);
  TrackResult track(const Frame& frame);
  const TrackerStats& stats() const { return stats_; }
  TrackingState state() const { return state_; }
  // Debug output (core/debug_frame.h), off by default. With a sink, the tracker marks the
  // features its estimators reject, and emit_debug_frame() (called by the stage right after
  // track()) hands the frame's record to the sink; the mapper is asked to list the last
  // `recent_invalid` invalidated points in its snapshots. Call before the first track().
  void set_debug_sink(DebugFrameSink* sink, int recent_invalid = 4096);
  // A prior map (core/map_io.h) was loaded into the mapper: start LOST, so the first frames
  // relocalize in it instead of initializing a new map. Call before the first track().
  void start_with_map();
  void emit_debug_frame(const Frame& frame, const TrackResult& result);

 private:
  void fill_debug_frame(const Frame& frame, const TrackResult& result, DebugFrame& d) const;
  void refresh_snapshot();
  int match_motion(const Pose& T, double radius);
  int match_local_map(const Pose& T, double radius);
  // The steps of track() (see the header comment); each returns the inliers of its pose T, or
  // whether the frame's pose was found.
  void extract(const Frame& frame);
  void extract_features(const cv::Mat& image, Features& out);  // the active pyramid
  bool track_initializing(const Frame& frame);
  bool track_with_map();
  // The constant-velocity prediction of this frame's pose (TrackerParams::prediction_max_scale).
  Pose predict_pose() const;
  int track_with_motion_model(const Pose& Tpred, Pose& T);
  int widened_motion_search(const Pose& Tpred, Pose& T);
  int local_map_fallback(const Pose& Tpred, Pose& T);
  int extend_with_local_map(Pose& T);
  int submotion_test(Pose& T, int inliers);
  bool update_state(const Pose& T, int inliers);
  bool handle_lost();
  // Rotation-only tracking (see the header comment). rotation_entry_ok: the last motion was a
  // turn on the spot (evaluated before track_with_map overwrites the state).
  bool rotation_entry_ok();
  bool rotation_exit_ok();
  // Median camera-frame depth of the matched points of last_ (of_last) or cur_ at its pose;
  // -1 with fewer than min_points.
  double median_depth(bool of_last, int min_points);
  bool track_rotation_only();
  int match_bearings(const Eigen::Matrix3d& R_cam_world, double radius);
  int estimate_rotation_pose(Pose& T, bool robust);
  void make_rotation_keyframe(const Features& f, const Pose& T_cam_world);

  // Correspondence k of the estimators' arrays (corr_*): feature j of cur_ and 3D point p.
  void set_correspondence(int k, int j, const Eigen::Vector3d& p);
  // Packs cur_'s matched features into corr_*, in feature order; returns their count.
  int pack_matches();
  int optimise(Pose& T);
  int robust_optimise(Pose& T, const Pose& guess);
  // Drops feature j's match for this frame (robust-estimator outlier or dropped sub-motion bin).
  void reject_match(int j);
  // One pass of the coherent sub-motion test (TrackerParams::submotion_chi2) on the current
  // inliers; returns the inlier count after the refit (`inliers` when nothing is dropped) and
  // whether anything was dropped. Its steps: bin_residuals (per PARSAC bin, under the tight
  // pose Te; returns the count binned and their squared-residual sum), flag_coherent_bins
  // (returns the bins to drop) and drop_and_refit.
  int reject_submotion(Pose& T, int inliers, bool* dropped_any);
  int bin_residuals(const Pose& Te, double* sum_sq);
  int flag_coherent_bins(double var);
  int drop_and_refit(Pose& T, int n, int inliers, bool* dropped_any);
  bool relocalize();
  bool relocalize_in(uint32_t epoch);  // against snap_ (the map relocalization_map chose)
  // Recovery: relocalization may pick a kept earlier map (MapSnapshot::kept) when place
  // recognition ranks its keyframe first; `*epoch` and the returned snapshot are the map tried.
  std::shared_ptr<const MapSnapshot> relocalization_map(uint32_t* epoch);
  bool has_kept_maps() const { return snap_ && !snap_->kept.empty(); }
  // The mapper merged this epoch's map into an earlier one (MapSnapshot::merged_from): the
  // previous frame's pose, points and ids and the velocity move into the merged map's frame.
  void follow_merge(const MapSnapshot& s);
  void maybe_send_keyframe(const Frame& frame);
  // Sec. 4 per-frame map updating: every SlamLink::observe_every_n tracked frames (not on a
  // frame just proposed as a keyframe, which the mapper checks anyway) the tracked features,
  // PARSAC's rejected points, the pose and the image go to the mapper (skipped when full).
  void maybe_send_observation(const Frame& frame);
  void start_from_init(const InitResult& init, const Frame& frame);
  void reset_map(const char* why);
  // The frame's result, filled once per frame: `found` publishes cur_.T, else the last good pose.
  void fill_result(TrackResult& r, bool found) const;
  void wait_for_mapper();

  TrackerParams params_;
  FeatureParams fparams_;
  CameraModel camera_;
  PinholeIntrinsics K_;
  std::shared_ptr<SlamLink> link_;
  FeatureExtractor extractor_;
  // TrackerParams::fast_motion_levels: the extractor on the deeper pyramid (null: off), used
  // from the first fast initialization attempt on; levels_ is the active pyramid's depth.
  std::unique_ptr<FeatureExtractor> fast_extractor_;
  bool fast_motion_ = false;
  int levels_ = 1;
  Features ref_fast_;  // the initializer's reference frame on the deeper pyramid
  Initializer initializer_;
  PoseEstimator estimator_;
  RobustPoseEstimator tight_;  // the sub-motion test's estimator (gate submotion_gate_px)
  InitResult init_result_;

  TrackingState state_ = TrackingState::kInitializing;
  uint32_t epoch_ = 0;
  uint32_t max_epoch_ = 0;     // the largest epoch number used (a new map takes the next)
  int64_t lost_since_ns_ = 0;  // stamp of the first LOST frame (TrackerParams::new_map_after_s)
  bool lost_since_pending_ = false;  // start_with_map: lost_since_ns_ is the first frame's stamp
  std::shared_ptr<const MapSnapshot> snap_;
  uint64_t snap_version_ = 0;

  cv::Mat gray_;
  // Current and previous frame: features and, per feature, the matched point (id, position,
  // snapshot row).
  struct FrameState {
    Features f;
    std::vector<int64_t> pid;
    std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> p;
    std::vector<int> row;
    std::vector<float> best_dist;
    Pose T;
    int64_t stamp_ns = 0;  // Frame::stamp_ns
    void reset_matches(int n);
  };
  FrameState cur_, last_;
  bool have_last_ = false;
  Pose velocity_;               // motion between the last two tracked frames (T_cur * T_prev^-1)
  int64_t velocity_dt_ns_ = 0;  // the stamp interval velocity_ spans; <= 0: unknown (per frame)
  int frames_since_kf_ = 0;
  int frames_since_obs_ = 0;
  int lost_frames_ = 0;
  int64_t frame_no_ = 0;
  uint32_t resets_served_ = 0;  // SlamLink::reset_requests handled

  // Scratch (preallocated).
  std::vector<int> cand_;
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> corr_p_;
  std::vector<Eigen::Vector2d, Eigen::aligned_allocator<Eigen::Vector2d>> corr_x_;
  std::vector<float> corr_s_;
  std::vector<int> corr_feat_;
  std::vector<uint8_t> corr_inl_;
  std::vector<int> reloc_pairs_;
  Relocalizer reloc_;  // place recognition and matching while LOST (sized by the map caps)
  cv::Mat ref_image_;  // image of the initializer's reference frame
  std::vector<int64_t> row_stamp_;  // per snapshot row: frame_no_ when matched this frame
  // Per snapshot row: track_no_ of the frame whose robust estimate rejected the point.
  std::vector<int64_t> row_rejected_;
  int64_t track_no_ = 0;  // frames tracked (frame_no_ also advances between search passes)
  std::vector<int> kf_votes_;
  // Sub-motion test scratch, per PARSAC bin and per correspondence.
  int bins_x_ = 10, bins_y_ = 10;
  std::vector<Eigen::Vector2d, Eigen::aligned_allocator<Eigen::Vector2d>> bin_sum_;
  std::vector<int> bin_count_, corr_bin_;
  std::vector<uint8_t> bin_flag_;
  std::vector<float> level_scale_;
  TrackerStats stats_;
  int ref_kf_shared_ = 0, ref_kf_points_ = 0;
  int ref_kf_id_ = -1;    // this frame's reference keyframe (TrackResult::ref_keyframe)
  Pose T_cam_ref_;        // this frame's pose relative to it
  double wait_ms_ = 0.0;  // this frame's time in wait_for_mapper() (reported, not tracking)
  // Debug output only (set_debug_sink): per feature of this frame, the DebugFeatureKind of
  // an estimator rejection (sized only when a sink is set).
  DebugFrameSink* debug_sink_ = nullptr;
  std::vector<uint8_t> debug_rejected_;
  // Rotation-only tracking: the rotation keyframe (features, unit world bearings), the held
  // centre, per current feature the matched bearing (-1) and its distance, the reference
  // keyframe (id, pose) the rotation-only poses are reported against, scratch for the depths.
  bool rotation_mode_ = false;
  Eigen::Vector3d rot_centre_ = Eigen::Vector3d::Zero();
  Features rot_kf_;
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> rot_bearing_;
  int rot_kf_matches_ = -1;  // matches on the first frame after the rotation keyframe
  Eigen::Matrix3d rot_kf_R_ = Eigen::Matrix3d::Identity();  // its R_cam_world
  double rot_ema_angle_ = 0.0, rot_ema_shift_ = 0.0;  // smoothed rotation, translation / depth
  std::vector<int> bear_of_;
  std::vector<float> bear_dist_;
  std::vector<int> corr_bear_;  // per correspondence: its bearing (>= 0) or -1 (a map point)
  int rot_ref_kf_id_ = -1;
  Pose rot_ref_T_;
  std::vector<double> depth_scratch_;
};

}  // namespace rdslam
