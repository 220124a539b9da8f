// The mapper (Sec. 3-4): turns the tracker's keyframe candidates (frames that met the
// tracker's keyframe conditions, m1 among them, core/tracker.h) into keyframes, and publishes a
// new matching index (core/match_index.h) for the tracker. A candidate goes through these
// steps (core/mapper.cpp, one private function each):
//  1. map updating on the candidate (Sec. 4, Algorithm 1, core/map_updater.h; only with
//     set_change_detection): invalid points and keyframes are marked, invalid keyframes go
//     (a map changed here is published even if the candidate is rejected);
//  2. insert the keyframe with the tracker's point matches as observations;
//  3. track triangulation with the related keyframes: the `related_keyframes` (5) sharing most
//     points, topped up with the most recent ones when fewer share any. Per related keyframe:
//     pair selection (baseline against median scene depth), epipolar matching of the free
//     features (core/matching.h, one-to-one), then per match two-view triangulation with the
//     parallax (`min_parallax_deg`), cheirality and reprojection checks and, with
//     dynamic.check_new_points, a third view (a recent frame must agree); then a new point;
//  4. condition m2 (Sec. 4 condition 3): the candidate becomes a keyframe only if it
//     contributed more than `m2` new points (with `m2_weak_tracking`, a candidate that tracked
//     fewer points than m2: more new points than it tracked); otherwise it goes with its new
//     points;
//  5. fusion by projection: the points of the related keyframes and of their 5 most covisible
//     keyframes into the new keyframe, its points into the related keyframes
//     (MatchPurpose::kFuse);
//  6. new tracks seen in >= 3 views get the multi-view estimate (Sec. 4's track equation:
//     reprojection error minimised over all views); the new keyframe's points get their
//     geometry and representative descriptor updated; with a vocabulary (SlamLink::vocabulary,
//     ORB) the keyframe's bag-of-words vector enters the place-recognition database
//     (core/keyframe_database.h), which each publish copies into the snapshot when keyframes
//     changed (removed keyframes leave it there);
//  7. local bundle adjustment (core/bundle_adjustment.h): the new keyframe and its most
//     covisible keyframes, `ba.window` keyframes in all; while the map is young (fewer than
//     `ba_young_keyframes`), `ba_young_window` of them, grown back towards `ba.window` while
//     they span fewer than `ba_young_span_frames` tracker frames (fast motion);
//  8. culling (bounded map), then publish.
// In localization-only mode (SlamLink::localize_only) candidates and observations are taken
// off their rings and ignored: the map stays as it is.
//
// Recovery (map epochs, docs/slam.md "Recovery"): a reset candidate (the tracker was LOST too
// long, core/tracker.h) starts a new map epoch. The current map is kept, frozen (no bundle
// adjustment, no updating, no culling), when it has more than 2 keyframes: at most
// `max_epochs` earlier maps are kept (the oldest goes first), each within the caps, so the
// mapper holds at most (max_epochs + 1) x (max_keyframes, max_points). Their keyframes stay in
// the place-recognition database and their last snapshots travel in every snapshot
// (MapSnapshot::kept), so the tracker can relocalize into them; a keyframe candidate of a kept
// epoch (the tracker relocalized there) makes that map current again (the current one is kept
// or, with at most 2 keyframes, dropped). After step 6 of a keyframe of the current map, each
// kept map is searched for it (place recognition in that epoch, then descriptor matches of
// their points, a Sim(3) RANSAC with at least `merge_min_inliers`, then at least
// `merge_min_matches` of the keyframe's features matched by projecting the candidate's and its
// covisible keyframes' points); on success the current map is merged into the kept one
// (core/map_merge.h: transformed into its frame, ids shifted, duplicates fused), which becomes
// the current map with the kept map's epoch (subscribers see pose_t.map_epoch return to the
// earlier map's, whose frame the poses continue in), then local BA around the seam.
//
// Culling, in this order:
//  - recent points: a point seen by fewer than 2 keyframes, or still by at most 2 at the second
//    or third keyframe after the one that created it, is removed (ORB-SLAM's rule; monocular
//    points need a third view to be trusted);
//  - keyframes: among the new keyframe's covisible keyframes, one (not fixed) whose points are
//    invalid (V(X) = 0) or observed by at least 3 other keyframes for more than
//    `redundant_fraction` (90%, Sec. 4) of its points is removed;
//  - caps: above `max_keyframes` the oldest keyframe goes (the next oldest becomes the fixed
//    gauge); points left with fewer than 2 observations go; above `max_points` the points
//    with the fewest observations (oldest first) go.
//
// Ownership: the Mapper owns the Map. Threads: mapper thread only (step()); in offline runs
// the single thread alternates tracker and mapper.
#pragma once

#include <deque>
#include <map>
#include <memory>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "core/bundle_adjustment.h"
#include "core/epipolar_bins.h"
#include "core/features.h"
#include "core/keyframe.h"
#include "core/keyframe_database.h"
#include "core/map.h"
#include "core/map_io.h"
#include "core/map_merge.h"
#include "core/map_updater.h"
#include "core/matching.h"
#include "core/params.h"
#include "core/stages.h"

namespace rdslam {

// A map save handed off by the mapper thread (Mapper::set_save_writer): a deep copy of what
// the file will hold (core/map_io.h copy_map_for_save), where it goes, and the link whose
// counters (saves_done, saves_failed) the writer updates.
struct MapSaveJob {
  Map map;
  CameraModel camera;
  FeatureParams features;
  std::string path;
  int keep = 1;
  int64_t saved_unix_s = 0;  // when the copy was taken (the file's save time)
  double copy_ms = 0.0;      // the copy's time on the mapper thread
  std::shared_ptr<SlamLink> link;
};

// Encodes and writes `job` on the calling thread (PNG encoding of the keyframe images, CRC,
// fsync'ed atomic write), counts the outcome in job.link and logs it. True when written.
bool run_map_save_job(const MapSaveJob& job);

// Where the mapper thread hands save jobs (implemented outside core/, which creates no
// threads: firmware_app/map_writer.h runs them on a low-priority thread). One job at a time:
// the mapper calls submit() only when busy() is false. Threads: busy() and submit() from the
// mapper thread.
class MapSaveWriter {
 public:
  virtual ~MapSaveWriter() = default;
  virtual bool busy() const = 0;
  virtual void submit(std::unique_ptr<MapSaveJob> job) = 0;
};

struct MapperParams {
  int m2 = 50;                      // paper Sec. 4: new points a keyframe must contribute
  int related_keyframes = 5;        // paper Sec. 4: the 5 most related keyframes
  int max_keyframes = 150;          // cap
  int max_points = 20000;           // cap
  double min_parallax_deg = 1.0;    // new points need this triangulation angle
  double redundant_fraction = 0.9;  // keyframe culling (Sec. 4's 90%)
  int max_epochs = 2;               // recovery: earlier maps kept frozen (0: none)
  int merge_min_inliers = 20;       // recovery: Sim(3) RANSAC inliers to merge
  int merge_min_matches = 50;       // recovery: features matched by projection to merge
  bool ba_yield = true;             // live: local BA stops when another keyframe waits
  // A candidate that tracked fewer map points than m2 (driving forward at a low frame rate:
  // the points in view run out) is kept when it contributes more new points than it tracked,
  // i.e. at least doubles them; m2 alone would refuse the keyframe the tracker needs most.
  bool m2_weak_tracking = true;
  // Young map (fewer than ba_young_keyframes keyframes): the local BA window is
  // ba_young_window keyframes, extended (up to ba.window) while its keyframes span fewer than
  // ba_young_span_frames tracker frames (fast motion, nearly every frame a keyframe).
  int ba_young_keyframes = 20;
  int ba_young_window = 6;
  int ba_young_span_frames = 15;
  BundleAdjustmentParams ba;

  void visit(ParamVisitor& v);
};

struct MapperStats {
  int keyframes_accepted = 0, keyframes_rejected = 0, keyframes_culled = 0;
  int points_created = 0, points_culled = 0;
  int last_new_points = 0;
  double last_ba_ms = 0.0;
  int last_ba_window = 0;  // keyframes in the last local BA's window (the new one included)
  int ba_yielded = 0;      // local BAs ended early or skipped for a waiting keyframe (ba_yield)
  int snapshots = 0;
  int points_invalidated = 0, keyframes_invalidated = 0;  // Sec. 4 updating (MapUpdater)
  int observations = 0;              // frame observations run through the updater
  int keyframes_replaced = 0;        // invalid keyframes removed from the map
  double update_ms_total = 0.0;      // wall time in MapUpdater::update (observations only)
  int points_counter_discarded = 0;  // of points_invalidated: by the missed/moved counters
  int points_pruned = 0;        // of points_culled: erased by the updater (dynamic.prune_unmatched)
  int points_rejected_new = 0;  // triangulated but not seen again (dynamic.check_new_points)
  int maps_started = 0;         // initializations (map epochs begun)
  int maps_kept = 0, maps_dropped = 0, maps_reactivated = 0;  // recovery (earlier maps)
  int merges = 0, merge_attempts = 0;                         // recovery: Sim(3) merges
};

class Mapper {
 public:
  Mapper(const MapperParams& params, const FeatureParams& features, const CameraModel& camera,
         std::shared_ptr<SlamLink> link);
  // Processes one candidate or, when no candidate waits (candidates are latency-critical),
  // one frame observation (core/keyframe.h), waiting up to `timeout_ms` for either. False if
  // there was none.
  bool step(int timeout_ms);
  const Map& map() const { return map_; }
  const MapperStats& stats() const { return stats_; }
  // Enables Sec. 4's online point and keyframe updating (core/map_updater.h): every keyframe
  // candidate (before it is inserted) and every frame observation of the tracker (every
  // dynamic.check_every_n_frames tracked frames) is checked against the map. Invalid
  // keyframes (the 90% rule) are removed at once, so the tracker's keyframe rule replaces them
  // with newly selected frames; invalid points leave the matching index at the next publish,
  // which an observation that invalidated anything triggers itself. With map_update off but
  // check_new_points on, the observations only feed the new-point check. Call before the
  // first step().
  void set_change_detection(const ChangeDetectionParams& p);
  // Final trajectory (replay, evaluation): with the trail on, every keyframe the mapper removes
  // leaves its pose relative to its most covisible keyframe (one small entry per removed
  // keyframe, cleared at a map reset; a growth a days-long run must not have, so it is off by
  // default). final_keyframe_pose() then gives the pose a keyframe of the current map epoch
  // has in the final map, through that chain for removed ones (ORB-SLAM's way of writing its
  // per-frame trajectory); false for another epoch or an unknown id. Call both while the
  // mapper thread is not running (before the first step(), after the last).
  void set_keep_trail(bool on) { keep_trail_ = on; }
  bool final_keyframe_pose(uint32_t epoch, int id, Pose* T_cam_world) const;
  // The scale by which poses of map epoch `epoch` were multiplied by the merges that moved that
  // map into the one that holds it now (1 when never merged): a frame's pose relative to its
  // reference keyframe (TrackResult::p_ref_cam) is scaled by it before final_keyframe_pose.
  double final_epoch_scale(uint32_t epoch) const;
  // The final pose (T_world_cam) of a frame the tracker posed with `r`: its pose relative to
  // its reference keyframe (scaled by final_epoch_scale) on that keyframe's final pose; false
  // when the keyframe is not in the final map (the online pose is then the best there is).
  // The one rule both the offline run and the threaded replay write final trajectories by.
  bool final_frame_pose(const TrackResult& r, Pose* T_world_cam) const;
  // The epochs of the earlier maps kept (oldest first); tests and diagnostics.
  std::vector<uint32_t> kept_epochs() const;
  // Prior maps (issue 24, core/map_io.h). load() replaces the (empty) map by `map`, rebuilds
  // its place-recognition vectors from the keyframes' descriptors and publishes it (with the
  // SIFT KD-tree), so the tracker can relocalize in it; call before the first step().
  // save() writes the current map to `path` atomically (keeping `keep` - 1 older versions) on
  // the calling thread, which must be the mapper thread or any thread while the mapper thread
  // is not running; returns false and sets *error when it could not (the previous file is left
  // as it was). `info` (optional) receives what was written and `*ms` the time it took.
  void load(Map&& map);
  bool save(const std::string& path, int keep, std::string* error, MapInfo* info = nullptr,
            double* ms = nullptr);
  // Where step() saves on a request (SlamLink::save_requests); empty: requests fail. Call
  // before the first step().
  void set_save_target(const std::string& path, int keep) {
    save_path_ = path;
    save_keep_ = keep;
  }
  // With a writer (not owned; it must outlive the mapper thread), step() serves a save request
  // by copying the map (copy_map_for_save, memory copies only) and handing the copy to the
  // writer, which encodes and writes it on its own thread; requests made while the writer is
  // busy wait and are served together by one copy once it is free (SlamLink::saves_coalesced).
  // Without one (nullptr, the default) step() encodes and writes on the mapper thread. Call
  // before the first step().
  void set_save_writer(MapSaveWriter* writer) { save_writer_ = writer; }
  // Diagnostics (tests): every invalidation from now on is appended to `log` (nullptr: off).
  void set_invalidation_log(std::vector<InvalidationRecord>* log) { inval_log_ = log; }
  // Diagnostics: every Algorithm 1 verdict (core/map_updater.h CheckRecord); tests only.
  void set_check_log(std::vector<CheckRecord>* log) {
    if (updater_) updater_->set_check_log(log);
  }

 private:
  void process(const KeyframeCandidate& c);
  void process_observation(const FrameObservation& o);
  void account(const MapUpdateStats& u);
  int remove_invalid_keyframes();
  void handle_init(const KeyframeCandidate& c);
  // The keyframe path (steps in order; see the header comment).
  bool update_on_candidate(const KeyframeCandidate& c);
  void handle_keyframe(const KeyframeCandidate& c);
  int insert_keyframe(const KeyframeCandidate& c, int* tracked);
  std::vector<int> related_keyframes(int kf) const;
  // `image`: the candidate's frame (dynamic.check_new_points compares windows in it). Appends
  // the new points' ids to `created`; returns their number.
  int triangulate(int kf, const std::vector<int>& related, const cv::Mat& image,
                  std::vector<int64_t>& created);
  Keyframe* triangulation_partner(const Keyframe& C, int rid);
  void match_epipolar(const Keyframe& C, const Keyframe& R, const std::vector<char>& used);
  bool triangulate_match(const Keyframe& C, const Keyframe& R, int j, int i, const cv::Mat& image,
                         Eigen::Vector3d& p);
  int64_t create_point(int kf, int rid, int j, int i, const Eigen::Vector3d& p);
  bool accept_keyframe(int kf, int n_new, int tracked, const std::vector<int64_t>& created,
                       const cv::Mat& image);
  int fuse(int kf, const std::vector<int>& related);
  int project_and_add(int64_t pid, int kf);
  void refine_new_tracks(const std::vector<int64_t>& created);
  void update_keyframe_points(int kf);
  void update_descriptor(MapPoint& p) const;
  void local_bundle_adjustment(int kf);
  void cull(int kf);
  void cull_recent_points();
  void cull_redundant_keyframes(int kf);
  void retire_keyframe(int kid);  // erase_keyframe, leaving a trail entry when keep_trail_
  void cap_keyframes(int kf);
  void cull_unobserved_points();
  void cap_points();
  void publish();
  std::shared_ptr<MapSnapshot> build_snapshot(const Map& m, uint32_t epoch) const;
  // Recovery (see the header comment).
  void start_epoch(uint32_t epoch);
  void freeze_current();
  bool reactivate(uint32_t epoch);
  bool try_merge(int kf, int* merged_kf);
  bool verify_merge(const Keyframe& A, const Keyframe& B, const Map& target, Sim3* S,
                    std::vector<std::pair<int, int64_t>>* matches) const;
  int match_by_projection(const Keyframe& A, const Keyframe& B, const Map& target, const Sim3& S,
                          std::vector<std::pair<int, int64_t>>* matches) const;
  void merge_into(size_t kept_index, const Sim3& S,
                  const std::vector<std::pair<int, int64_t>>& matches, int kf, int* merged_kf);
  // The map of `epoch` after following its merges: epoch, keyframe id and scale.
  bool resolve_merges(uint32_t* epoch, int* id, double* scale) const;
  void add_place(int kf);  // place recognition: the keyframe's vector into the database
  void fill_recent_invalid(MapSnapshot& s);
  void serve_save_requests();

  MapperParams params_;
  FeatureParams fparams_;
  PinholeIntrinsics K_;
  CameraModel camera_;  // with its lens: map updating's eq. (2) windows (core/map_updater.h)
  std::shared_ptr<SlamLink> link_;
  Map map_;
  uint32_t epoch_ = 0;
  uint64_t version_ = 0;
  MapperStats stats_;
  std::vector<int> cand_;
  ClaimTable claims_;  // triangulation: new keyframe feature -> related keyframe feature
  // Epipolar search scratch (match_epipolar): R's free features and their bins.
  EpipolarBins epi_bins_;
  std::vector<int> r_free_;
  std::vector<double> r_x_, r_y_, r_band_;
  std::unique_ptr<MapUpdater> updater_;
  // Place recognition (with SlamLink::vocabulary, ORB): keyframes' bag-of-words vectors, built
  // into MapSnapshot::places at each publish.
  std::unique_ptr<KeyframeDatabaseBuilder> places_;
  BowVector bow_;
  Vocabulary::Scratch voc_scratch_;
  struct Trail {
    int parent = -1;
    Pose T_kf_parent;  // removed keyframe's pose relative to `parent` when it was removed
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  bool keep_trail_ = false;
  std::unordered_map<int, Trail> trail_;
  // Recovery: earlier maps kept frozen (oldest first) and the merges done.
  struct KeptMap {
    uint32_t epoch = 0;
    Map map;
    std::unordered_map<int, Trail> trail;
    std::shared_ptr<const MapSnapshot> snapshot;
  };
  std::vector<std::unique_ptr<KeptMap>> kept_;
  struct MergeRecord {
    uint32_t into = 0;
    Sim3 S;
    int kf_offset = 0;
    int64_t point_offset = 0;
  };
  std::map<uint32_t, MergeRecord> merges_;  // by the epoch merged away
  int64_t last_merged_from_ = -1;           // into the current map (MapSnapshot::merged_from)
  MergeRecord last_merge_;
  PlaceQueryScratch merge_query_;
  std::vector<InvalidationRecord>* inval_log_ = nullptr;
  // Debug output only (SlamLink::debug_recent_invalid > 0): points seen invalid at a publish,
  // oldest first, bounded; and which ids were already listed (this map epoch).
  std::deque<std::pair<int64_t, Eigen::Vector3d>> recent_invalid_;
  std::unordered_set<int64_t> invalid_seen_;
  uint32_t recent_invalid_epoch_ = 0;
  // Save requests (SlamLink::save_requests): where, how many versions, how many served.
  std::string save_path_;
  int save_keep_ = 1;
  uint32_t saves_served_ = 0;
  MapSaveWriter* save_writer_ = nullptr;
};

}  // namespace rdslam
