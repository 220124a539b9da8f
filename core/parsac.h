// PARSAC: prior-based adaptive RANSAC for camera pose from 2D-3D correspondences (RDSLAM,
// Tan et al., ISMAR 2013, Sec. 5), with its baselines behind the same interface:
//  - ransac:     uniform minimal samples, score = inlier count, standard adaptive termination
//                (Fischler & Bolles 1981);
//  - lo-ransac:  ransac plus local optimisation of every new best model (Chum et al. 2003);
//  - arsac:      PARSAC without the inlier-ratio prior (the paper's own ablation): bin sampling
//                with uniform bin probabilities, eq. (4)/(5) scoring, eq. termination;
//  - parsac:     10x10 bins, at most one point per bin in each sample, bins drawn with
//                p_i = eps*_i / sum_j eps*_j where eps*_i is the previous frame's inlier ratio
//                of bin i truncated to [0.2, 1]; score s = (sum eps_i) pi sqrt(det C) / A with
//                the weighted bin-centre covariance C of eq. (4); stop when
//                (1 - (sum_i p_i eps^_i)^m)^K < eta;
//  - magsac-ref: OpenCV solvePnPRansac with MAGSAC++ scoring (outside reference; allocates).
// Every method ends the same way (Sec. 5): the best model is re-estimated from all its
// inliers (DLT on all inliers for the dlt6 solver), decomposed into R and T, and refined by
// minimising the reprojection error of eq. (1) (core/pose_refine.h).
//
// Minimal solvers: dlt6 (the paper's projective matrix, m = 6) or p3p (calibrated, m = 4: three
// points for P3P and a fourth to pick among its up to four solutions).
//
// Ownership: one RobustPoseEstimator per camera stream; it owns all its buffers (allocated in
// the constructor) and the per-bin inlier-ratio prior, which survives from frame to frame.
// Threads: one thread (the tracker's) calls estimate(); the object is not shared. estimate()
// does not allocate on the heap for the methods ransac, lo-ransac, arsac and parsac.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/params.h"
#include "core/pose_solvers.h"

namespace rdslam {

// Config section `parsac`. Names and defaults follow Sec. 5 where the paper gives them; the
// others are marked "not in the paper".
struct ParsacParams {
  std::string method = "parsac";  // ransac | lo-ransac | arsac | parsac | magsac-ref
  std::string solver = "p3p";     // dlt6 (paper, m = 6) | p3p (calibrated, m = 4)
  int bins_x = 10;                // Sec. 5: "we evenly divide the whole image to 10x10 bins"
  int bins_y = 10;
  double prior_min = 0.2;  // Sec. 5: previous inlier ratio truncated to [0.2, 1]
  double prior_max = 1.0;
  double eta = 0.01;         // termination (1 - (sum p_i eps^_i)^m)^K < eta; value not in the paper
  int max_iterations = 500;  // hypothesis budget per frame (Table 1 uses 500)
  int min_iterations = 0;    // run at least this many (0: termination decides)
  double inlier_threshold_px = 3.0;  // reprojection error of an inlier; not in the paper
  int min_inliers = 12;              // fewer final inliers -> kNoModel; not in the paper
  int refine_iterations = 10;        // LM iterations of eq. (1) per refinement round
  int lo_inner_iterations = 10;      // lo-ransac: inner samples per local optimisation
  int seed = 1;                      // random stream; same seed -> same results

  void visit(ParamVisitor& v);
  // Cross-field checks; empty when valid, otherwise a message naming the key.
  std::string validate() const;
};

enum class RobustMethod : uint8_t { kRansac, kLoRansac, kArsac, kParsac, kMagsacRef };
enum class MinimalSolver : uint8_t { kDlt6, kP3P };
// Parse the config strings; return false for unknown names.
bool parse_robust_method(const std::string& name, RobustMethod* out);
bool parse_minimal_solver(const std::string& name, MinimalSolver* out);
const char* to_string(RobustMethod m);
const char* to_string(MinimalSolver s);
// Sample size m of a solver: 6 for dlt6, 4 for p3p.
int sample_size(MinimalSolver s);

enum class PoseStatus : uint8_t {
  kOk = 0,
  kTooFewPoints,  // fewer than m usable points, or fewer than m occupied bins (bin samplers)
  kNoModel,       // no hypothesis reached min_inliers
  kBadInput,      // count > max_points or null pointers
};
const char* to_string(PoseStatus s);

struct PoseEstimate {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();  // X_cam = T_cam_world X_world
  PoseStatus status = PoseStatus::kNoModel;
  int inlier_count = 0;         // after refinement, with inlier_threshold_px
  int iterations = 0;           // minimal samples drawn
  int best_iteration = 0;       // iteration that produced the kept hypothesis (0: the guess)
  int required_iterations = 0;  // K from the termination criterion for the kept hypothesis
  double score = 0.0;           // eq. (5) (arsac, parsac) or inlier count (ransac, lo-ransac)
  double rms_error_px = 0.0;    // RMS reprojection error of the final inliers
};

class RobustPoseEstimator {
 public:
  // Throws std::invalid_argument on invalid params (start-up boundary). `max_points` bounds
  // `count` in estimate(); all buffers are sized here.
  RobustPoseEstimator(const ParsacParams& params, const CameraModel& camera, int max_points);

  // pixels: undistorted pixel coordinates; p_world: world points; count <= max_points.
  // T_cam_world_guess (optional) is scored as an extra hypothesis before sampling.
  // inlier_mask (optional, count bytes) receives 1 for inliers, 0 otherwise.
  // Returns result->status. Never throws.
  PoseStatus estimate(const Eigen::Vector2d* pixels, const Eigen::Vector3d* p_world, int count,
                      const Eigen::Isometry3d* T_cam_world_guess, uint8_t* inlier_mask,
                      PoseEstimate* result);

  // Forget the inlier-ratio prior (all bins back to prior_max): after relocalization or a jump.
  void reset_prior();
  // Restart the random stream.
  void reseed(uint64_t seed);

  const ParsacParams& params() const { return params_; }
  RobustMethod method() const { return method_; }
  MinimalSolver solver() const { return solver_; }
  int max_points() const { return max_points_; }
  int bin_count() const { return bins_x_ * bins_y_; }
  // Bin of a pixel (clamped to the image), row-major: by * bins_x + bx.
  int bin_of(double u, double v) const;
  // The per-bin truncated prior eps*_i used by the next estimate() (bin_count() values).
  const double* bin_prior() const { return prior_.data(); }
  // Bin sampling probabilities p_i of the last estimate() (0 for empty bins; uniform over
  // occupied bins for arsac). Only meaningful for arsac and parsac.
  const double* last_bin_probabilities() const { return probs_.data(); }
  // Inlier ratio eps^_i of the best hypothesis of the last estimate(), per bin.
  const double* last_best_bin_inlier_ratio() const { return best_eps_.data(); }

  // Test hook: called with the point indices of every minimal sample (no allocation).
  using SampleObserver = void (*)(void* context, const int* indices, int m);
  void set_sample_observer(SampleObserver fn, void* context) {
    observer_ = fn;
    observer_ctx_ = context;
  }

 private:
  bool draw_sample(int* idx);
  bool make_hypotheses(const int* idx, int* n_hyp);
  double evaluate(const Mat34& P, int* bin_inliers, int* total_inliers);
  double score_of(const int* bin_inliers, int total_inliers);
  double inlier_probability(const int* bin_inliers, int total_inliers) const;
  void local_optimise(Mat34* P_best, double* best_score, int* best_bins, int* best_total);
  int collect_inliers(const Mat34& P, double threshold_px, uint8_t* mask) const;
  void finish(const Mat34& P_best, bool refit_dlt, uint8_t* inlier_mask, PoseEstimate* result);
  PoseStatus estimate_magsac(uint8_t* inlier_mask, PoseEstimate* result);
  uint64_t next_u64();
  double next_double();
  int next_int(int n);

  ParsacParams params_;
  RobustMethod method_ = RobustMethod::kParsac;
  MinimalSolver solver_ = MinimalSolver::kP3P;
  Intrinsics K_;
  int width_ = 0, height_ = 0;
  int bins_x_ = 10, bins_y_ = 10;
  int max_points_ = 0;
  int m_ = 4;
  uint64_t rng_[4] = {0, 0, 0, 0};

  // Per-frame views of the caller's arrays.
  const Eigen::Vector2d* px_ = nullptr;
  const Eigen::Vector3d* pw_ = nullptr;
  int n_ = 0;

  // Preallocated per-point buffers (max_points).
  std::vector<int> point_bin_;   // bin of each point, -1 if unusable (non-finite)
  std::vector<int> valid_idx_;   // usable points
  std::vector<int> valid_bin_;   // bin of each usable point (valid_idx_ order)
  std::vector<double> soa_;      // X, Y, Z, u, v columns of the usable points (hot loop)
  std::vector<uint8_t> flags_;   // inlier flags of the hypothesis being scored
  std::vector<int> bin_points_;  // points grouped by bin (counting sort)
  std::vector<int> inlier_idx_;  // scratch for lo-ransac inner samples
  std::vector<uint8_t> mask_a_, mask_b_;
  std::vector<Eigen::Vector3d> bearing_;  // K^-1 x normalised (p3p)
  // Preallocated per-bin buffers (bins).
  std::vector<int> bin_start_, bin_size_;
  std::vector<int> occupied_;       // occupied bin ids
  std::vector<double> cumulative_;  // cumulative sampling weights over occupied_
  std::vector<double> prior_, probs_, best_eps_;
  std::vector<int> bins_scratch_, best_bins_;
  std::vector<Eigen::Vector2d> bin_centre_;
  std::vector<Eigen::Vector2d> occ_centre_;  // centres of the occupied bins, in occupied_ order
  std::vector<double> occ_weight_;           // their inlier ratios (scoring scratch)
  std::vector<uint8_t> occ_flag_;            // per bin: has points this frame
  int n_valid_ = 0, n_occupied_ = 0;
  Eigen::Vector3d world_centre_{0, 0, 0};
  double world_scale_ = 1.0;
  Mat34 hyp_[4];

  SampleObserver observer_ = nullptr;
  void* observer_ctx_ = nullptr;
};

// ---- Pieces of Sec. 5 exposed for unit tests and tools ----

// Eq. (4): weighted covariance of the points x[0..n) with weights w[0..n) (bin inlier ratios;
// zero-weight entries are ignored). Returns false when it is undefined ((sum w)^2 == sum w^2,
// i.e. fewer than two bins with weight).
bool weighted_covariance(const Eigen::Vector2d* x, const double* w, int n, Eigen::Matrix2d* C);
// Eq. (3): sample covariance of x[0..n), n >= 2.
Eigen::Matrix2d sample_covariance(const Eigen::Vector2d* x, int n);
// Eq. (5): s = (sum eps) * pi * sqrt(det C) / A.
double parsac_score(double sum_eps, const Eigen::Matrix2d& C, double image_area);
// Smallest K with (1 - q^m)^K < eta, q the probability that one drawn point is an inlier
// (sum_i p_i eps^_i for PARSAC). Saturates at INT32_MAX; q >= 1 gives 1.
int required_iterations(double q, int m, double eta);
// Bin sampling probabilities: p_i = clamp(prior_i, lo, hi) / sum_j over occupied bins
// (occupied[i] != 0); 0 for empty bins. Writes n values.
void truncated_prior_probabilities(const double* prior, const uint8_t* occupied, int n, double lo,
                                   double hi, double* p);

}  // namespace rdslam
