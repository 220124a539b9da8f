// Scene-change detection of RDSLAM Section 4 ("For each input frame, we also need to measure
// whether parts of the scene have changed") and Algorithm 1 (3D point updating with
// occlusion handling), plus the landmark miss/moved counters and the optical-flow keypoint
// rejection for a stationary camera of the second paper (Sections 3.3 and 4.2).
//
// These are pure functions and small value types over the inputs the SLAM map provides; the
// map owns the points and keyframes and applies the decisions. Buffers passed in are owned
// by the caller. Threads: any thread, no shared state; the SLAM system calls them from the
// mapper thread (see core/slam.h).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>

#include "core/params.h"

namespace rdslam {

struct ChangeDetectionParams {
  bool map_update = true;          // --no-map-update ablation (Figure 9) when false
  bool occlusion_handling = true;  // --no-occlusion-handling ablation (Figures 4-5) when false
  int closest_keyframes = 5;       // "we select 5 closest keyframes"
  double keyframe_view_angle_deg = 30.0;  // Z-axis direction difference to pre-select keyframes
  // Sum of R,G,B histogram distances that triggers the point check. Deviation: default 0
  // (always check) instead of the paper's 1: a global histogram does not see a local change
  // (measured on synth:rearrange: a poster moving across the view never exceeds 1, 0 points
  // checked); the cost is bounded by check_every_n_frames instead.
  double histogram_threshold = 0.0;
  // Option (deviation when on): also check the valid points in view that none of the selected
  // keyframes holds, each against its nearest observing keyframe within keyframe_view_angle_deg.
  // Where the camera sees a place from a new viewpoint the closest keyframes are newer ones
  // that never saw the old points there, so with the paper's selection a change (a box removed
  // while the camera was elsewhere) is never checked. Off by default: those points are also the
  // ones a static surface hides from nearby viewpoints, and Algorithm 1 then invalidates more
  // occluded points (synth:rearrange seeds 1-3: recall +3.7..+6.5 points, precision +0.2..-1.4
  // points; walking_halfsphere false invalidations 113 -> 272; docs/slam.md round E).
  bool check_all_in_view = false;
  double tau_n = 0.8660254037844387;  // cos(30 deg): compare appearance only if n_x.n_x' >= tau_n
  int window = 11;                    // W(x): 11x11 appearance window (eq. 2)
  int search_d = 2;                   // local search radius |d| in pixels (eq. 2)
  // tau_c on D_c normalised per pixel and channel (mean absolute difference in grey levels
  // 0..255): the paper's sum over the window divided by window area and channel count, so the
  // threshold does not depend on the window size.
  double tau_c = 25.0;
  // Eq. (2) on photometrically normalised windows (see appearance_difference()): a global
  // exposure step or a light spot is not a scene change. false: the paper's plain SAD, with
  // tau_c. true: the relative residual, with tau_c_relative. 0.8 corresponds, for Gaussian
  // textures, to a normalised cross-correlation of about 0.68 between the two windows
  // (E|a-b| / E|a| = sqrt(2 (1 - rho))): above it the current window explains less than
  // two thirds of the keyframe's texture, the usual acceptance bound of patch matchers
  // (0.7-0.8); a 1-2 px misregistration of a blurred texture stays well below it.
  bool normalise_appearance = true;
  double tau_c_relative = 0.8;
  // Eq. (2)'s local search d extended along X's ray in the reference keyframe over X's depth
  // uncertainty (ray_search_sigmas times the depth error a feature-scale bearing error gives at
  // X's widest triangulation angle, clamped to [kMinRayDepthRatio, kMaxRayDepthRatio]).
  // Deviation: the paper searches a small d around the projection, assuming an accurate depth;
  // a monocular point triangulated over a short baseline is often several pixels off in a new
  // view (measured on synth:rearrange: 199 of 200 false invalidations projected >= 8 px from
  // the true surface point), so without it a static, visible point "changes".
  bool ray_search = true;
  double ray_search_sigmas = 3.0;
  // What replaced X (see NewSurface): the current window at x' is compared with the previous
  // checked frame's window at X's projection (eq. (2), same tau: moving or static) and, when
  // static, matched along x's ray into the recent frame with the widest baseline (its depth:
  // in front of X or not), the depth confirmed in a third recent frame (about half that
  // baseline: a moving object's own motion along the epipolar line mimics a depth in two
  // views, not in three). Addition to Algorithm 1 in the spirit of the second paper's
  // optical-flow test, for the case the paper leaves open (nothing tracked near x'). Frames
  // older than temporal_max_gap_s are not used; temporal_depth_margin is the relative depth
  // below z_X that counts as "in front".
  bool temporal_check = true;
  // With temporal_check: X is invalidated only when the check finds a static surface at or
  // behind X (kBehind). false: where the check cannot decide (no baseline, flat or split
  // window), the paper's Algorithm 1 decides from the tracked neighbours alone. Default true:
  // on synth:rearrange it removes most false invalidations (windows straddling a static
  // occluder's silhouette, where Alg. 1 sees only the tracked background) at a small recall
  // cost (docs/slam.md, "Map updating").
  bool require_static_evidence = true;
  double temporal_max_gap_s = 1.0;
  double temporal_depth_margin = 0.1;
  // New points (not in the paper): a point the mapper triangulates from two keyframes is kept
  // only if its window in the new keyframe is seen again (eq. (2), tau_c) at its projection
  // into the oldest recent checked frame (widest baseline). Two views cannot tell a feature
  // on an object that moved between them (along the epipolar line) from a static one at
  // another depth; a third view can. Undecidable (no recent frame, outside the image) keeps.
  bool check_new_points = true;
  double r1 = 20.0;  // phi(x'): tracked points within r1 pixels of x'
  double r2 = 20.0;  // |x_p - y_p| < r2 in the keyframe where X first appeared
  // Per-frame updating (core/map_updater.h): the tracker hands the mapper every n-th tracked
  // frame (0: keyframe candidates only, as before).
  int check_every_n_frames = 3;
  // Only established points are checked: observed by at least this many keyframes. Deviation
  // (the paper checks every valid point): a two-view monocular point is often badly
  // triangulated (the mapper culls those that find no third view), projects off its surface
  // and so "changes appearance" without any scene change.
  int min_observations = 3;
  // Consecutive checks that must find X changed before V(X) = 0 (1: the paper's immediate
  // decision). Deviation: a change is a lasting state, while a moving object's edge, motion
  // blur or a one-frame pose error produce one-off verdicts.
  int confirm_checks = 2;
  // Second paper: per-landmark counters (miss threshold 10, moved threshold 5 observations).
  bool landmark_counters = true;
  // The miss counter (see core/map_updater.h: counted only for Alg. 1's "occluded by an
  // untracked object" verdict) is off by default: it assumes a moving occluder passes, and an
  // object held in front of the camera (rigid_object's book) stays; it then discards the
  // static points behind it (measured rigid_object, seeds 1-3: mean ATE 0.512% with, 0.465%
  // without; rearrange: it finds moved poster points over a plain wall).
  bool count_missed = false;
  int miss_threshold = 10;
  // The second paper's miss counter where it cannot hurt occlusion handling: a valid point that
  // is in view, within the distance range the tracker matches it at, looks unchanged (eq. (2)
  // D_c <= tau_c, so it is neither occluded nor changed) and has a tracked feature within 3 px
  // of its projection, yet is not matched itself, duplicates a point the tracker uses (a
  // surface mapped twice, e.g. after relocalizing). After more than miss_threshold such checks
  // in a row it is erased from the map (pruned, not invalidated: nothing about the scene
  // changed). Without it a long run keeps the copies and the map grows slowly; without the
  // duplicate condition it also erases lone background points the tracker matches only now
  // and then (docs/slam.md "Endurance" and deviations table).
  bool prune_unmatched = true;
  int moved_threshold = 5;
  // Second paper, Sec. 3.3/4.2: optional dense optical-flow rejection of candidate points while
  // the camera is stationary.
  bool flow_rejection = false;
  double flow_threshold_px = 1.0;         // flow magnitude above which a candidate is rejected
  double stationary_translation = 0.002;  // camera moved less than this (map units) per frame
  double stationary_rotation_deg = 0.2;   // and rotated less than this per frame

  // The mapper needs a MapUpdater and the tracker's frame observations for per-frame updating
  // or, with map_update off, for check_new_points' recent frames.
  bool needs_updater() const { return map_update || check_new_points; }
  // SlamLink's observation rate: every check_every_n_frames tracked frames, 0 when unused.
  int observe_every_n() const { return needs_updater() ? check_every_n_frames : 0; }

  void visit(ParamVisitor& v);
};

// R, G, B histograms with 256 bins each, every channel L2-normalised (sum c_i^2 = 1).
struct ColorHistogram {
  std::array<float, 3 * 256> bins{};
  bool valid = false;
};

// Computes the histogram of a BGR8 (or grey, used for all three channels) image, sampling
// every `stride`-th pixel in x and y. No allocation.
void compute_color_histogram(const cv::Mat& image, int stride, ColorHistogram& out);
// Sum over R, G, B of the Euclidean distance between the normalised histograms.
double histogram_difference(const ColorHistogram& a, const ColorHistogram& b);

// Index of keyframes ranked for the change check: those whose optical axis is within
// `max_angle_deg` of the current one, closest camera centres first, at most `k` of them.
// z_axes/centres are world-frame unit optical axes and camera centres. Returns the count
// written to `out` (capacity `out_capacity`). No allocation.
int select_closest_keyframes(const Eigen::Vector3d& cur_z_axis, const Eigen::Vector3d& cur_centre,
                             const Eigen::Vector3d* z_axes, const Eigen::Vector3d* centres,
                             int count, double max_angle_deg, int k, int* out, int out_capacity);

// Eq. (2): D_c(X) = min_d sum_{y in W(x)} |I_y - I_{y'+d}|, normalised per pixel and channel
// (normalise = false) or relative to the keyframe window's contrast (normalise = true).
// y' = x' + s (y - x) maps the keyframe window into the current image, with s the scale ratio
// (depth in keyframe / depth in current frame), i.e. a fronto-parallel patch at the
// estimated depth. Both images BGR8 or both grey. Returns +inf when a window leaves an image.
//
// normalise = true (dynamic.normalise_appearance, the default; a deviation from the paper's
// plain colour SAD): each window is made zero-mean and the current window is scaled by the
// gain g = sum|I_kf - mean_kf| / sum|I_cur - mean_cur| (clamped to
// [1/kMaxAppearanceGain, kMaxAppearanceGain]) before the SAD, which stays in the keyframe's
// grey levels so tau_c keeps its meaning; mean and gain are shared by the three channels.
// Why bias + gain: a camera's exposure/gain step and a (white) light spot larger than the
// 11x11 window are, over that window, an affine intensity change I' = a I + b, the same for
// every channel; this model removes exactly that and nothing else (per-channel means and gains
// would also remove the window's colour balance: a blue poster replaced by an orange photo of
// equal structure would look unchanged; measured on synth:rearrange, shared: recall 60.7%,
// per channel: 51.5%, precision 56.1% / 56.8%, flashlight's ATE unchanged). Unlike NCC-only scores
// it keeps the SAD's sensitivity to a texture that changed). Why the clamp: a texture replaced by
// a flat surface (an object moved away from a plain wall) would otherwise be amplified back to
// the keyframe's contrast; a ratio beyond 4 is not a lighting change a camera produces within
// one window. Shading that varies inside the window (a spot's edge) is not modelled.
//
// The normalised score is relative: the SAD divided by the keyframe window's own sum of
// absolute deviations (0: identical up to gain and bias; 1: the current window is flat, the
// texture is gone; about 1.4: an unrelated texture of equal contrast). An absolute threshold
// would not work on normalised windows: a keyframe window of mean contrast below tau_c could
// never exceed it, however completely it changed. A keyframe window whose mean absolute
// deviation is below kMinAppearanceContrast grey levels (sensor noise level) is not compared
// (+inf): it has no texture whose change could be seen.
constexpr int kMaxAppearanceWindow = 31;
constexpr double kMinRayDepthRatio = 0.05;  // ray search covers depth z/(1+r) .. z(1+r)
constexpr double kMaxRayDepthRatio = 0.5;
constexpr int kMaxRaySamples = 64;
constexpr int kMaxDepthSamples = 48;  // temporal check: samples along x's ray
constexpr double kMaxAppearanceGain = 4.0;
constexpr double kMinAppearanceContrast = 4.0;
//
// accept (optional): the shifts d are tried from the centre outwards and the first one whose
// score is <= accept is returned at once (the minimum is not needed to know that the window
// is unchanged); the default (-inf) computes the minimum over all shifts.
double appearance_difference(const cv::Mat& keyframe_image, const Eigen::Vector2d& x,
                             const cv::Mat& current_image, const Eigen::Vector2d& x_prime,
                             double scale, int window, int search_d, bool normalise = false,
                             double accept = -std::numeric_limits<double>::infinity());
// The same with a general linear warp of the window: the current image is sampled at
// y' = x' + A (y - x + d) (the form above: A = scale I). A lens stretches a window differently
// at x in the keyframe and at x' in the current frame: with x, x' raw pixels, A = scale J' J^-1
// (J, J' the lens's CameraModel::distort_jacobian there; core/map_updater.cpp).
double appearance_difference(const cv::Mat& keyframe_image, const Eigen::Vector2d& x,
                             const cv::Mat& current_image, const Eigen::Vector2d& x_prime,
                             const Eigen::Matrix2d& warp, int window, int search_d,
                             bool normalise = false,
                             double accept = -std::numeric_limits<double>::infinity());

// A tracked point y of the current frame near x': its pixel, its 3D point X_y's depth in the
// current camera, and X_y's projection into the keyframe where X first appeared.
struct NeighbourPoint {
  Eigen::Vector2d pixel;
  double depth_current = 0.0;               // z_{X_y}
  Eigen::Vector2d pixel_in_first_keyframe;  // y_p
  bool in_first_keyframe = false;           // y_p inside that keyframe's image and in front
};

enum class PointDecision : uint8_t {
  kKeepViewAngle = 0,      // n_x . n_x' < tau_n: keep V(X) = 1 (possibly not visible)
  kKeepSameAppearance,     // D_c <= tau_c
  kKeepOccludedMoving,     // phi(x') empty: occluded by a moving (never tracked) object
  kKeepOccludedStatic,     // a nearer tracked point far from X in the first keyframe: occlusion
  kInvalidNothingInFront,  // all neighbours at or behind X: X itself changed
  kInvalidSameObject,      // a nearer neighbour close to X in the first keyframe: X changed
  kInvalidNoOcclusionHandling,  // ablation: D_c > tau_c invalidates directly
  kKeepNotChecked,              // window outside the image or no appearance available
  kInvalidStaticChange,         // phi(x') empty but the new appearance at x' is static
  kKeepUndecided,               // require_static_evidence: no static surface found at/behind X
};

// What the current frame shows at x' where X looks changed (temporal_check): compared with
// recent frames, is it moving, or a static surface in front of X, or at/behind X?
enum class NewSurface : uint8_t {
  kUnknown = 0,  // not decidable (no recent frames, too little baseline, window flat/outside)
  kMoving,       // differs from the previous frame at X's projection: a moving object
  kInFront,      // static, and two-view matching puts it clearly in front of X: an occluder
  kBehind,       // static, at X's depth or behind it: X's surface changed or left
};

inline bool is_invalidation(PointDecision d) {
  return d == PointDecision::kInvalidNothingInFront || d == PointDecision::kInvalidSameObject ||
         d == PointDecision::kInvalidNoOcclusionHandling ||
         d == PointDecision::kInvalidStaticChange;
}
const char* to_string(PointDecision d);

// Algorithm 1 for one point X that is valid in a selected keyframe:
//  n_x, n_x_prime: unit viewing directions from X to the keyframe / current camera centres;
//  d_c: appearance difference of eq. (2) (pass +inf when it could not be computed);
//  depth_x: z_X, depth of X in the current camera; x_p: X's projection into the keyframe where
//  it first appeared; neighbours: phi(x'), the tracked points within r1 of x' (the caller
//  gathers them, e.g. with a grid);
//  seen: what the frame shows at x' (temporal_check, NewSurface). kMoving keeps V(X) = 1 (a
//  moving object is in front of X, whatever the neighbours say); kInFront keeps it (a static
//  occluder, the case Alg. 1 resolves with r2 when the occluder is tracked); kBehind turns
//  "phi(x') empty: occluded by a moving object" into kInvalidStaticChange (what replaced X
//  does not move and is not in front of X: X's surface changed, and nothing trackable, e.g. a
//  plain floor, took its place); kUnknown is the paper's Algorithm 1 unchanged, or, with
//  require_static_evidence, keeps V(X) = 1 (kKeepUndecided) as every verdict but kBehind does.
PointDecision update_point_validity(const ChangeDetectionParams& p, const Eigen::Vector3d& n_x,
                                    const Eigen::Vector3d& n_x_prime, double d_c, double depth_x,
                                    const Eigen::Vector2d& x_p, const NeighbourPoint* neighbours,
                                    int neighbour_count, NewSurface seen = NewSurface::kUnknown);

// Second paper, Sec. 4.2: per-landmark counters.
struct LandmarkCounters {
  uint16_t missed = 0;
  uint16_t moved = 0;
};
enum class LandmarkEvent : uint8_t { kMatchedStill, kMatchedMoved, kMissed };
// Applies one observation; returns true when the landmark must be discarded.
bool update_landmark_counters(LandmarkCounters& c, LandmarkEvent e, int miss_threshold,
                              int moved_threshold);

// True when the camera moved less than the stationary thresholds between two poses
// (T_world_cam as rotation + centre).
bool camera_is_stationary(const ChangeDetectionParams& p, const Eigen::Matrix3d& R_prev,
                          const Eigen::Vector3d& c_prev, const Eigen::Matrix3d& R_cur,
                          const Eigen::Vector3d& c_cur);

// Second paper, Sec. 3.3: rejects candidate keypoints lying on image regions whose dense
// optical-flow magnitude exceeds `flow_threshold_px` (camera stationary, so any flow is scene
// motion). `flow` is a CV_32FC2 field from cv::calcOpticalFlowFarneback (the paper used
// Horn-Schunck; Farneback is OpenCV 4's dense equivalent). keep[i] is set to 0 for rejected
// points. Returns the number rejected.
int reject_by_flow(const cv::Mat& flow, const float* xs, const float* ys, int count,
                   double flow_threshold_px, uint8_t* keep);

}  // namespace rdslam
