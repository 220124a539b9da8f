// Trajectory evaluation: association of an estimate with ground truth, Umeyama alignment
// (Sim3 / SE3 / none), absolute trajectory error (ATE) and relative pose error (RPE).
//
// The definitions follow evo (github.com/MichaelGrupp/evo, v1.38) so that numbers can be
// compared one to one (tests/unit/test_trajectory_eval_evo.cpp checks it to 1e-6 m):
// - association: the trajectory with fewer poses (the estimate when equal) is matched, pose
//   by pose, to the nearest stamp of the other within `max_diff_ns` (ties: the earlier one);
//   KITTI files carry no time and are associated by index;
// - alignment: Umeyama (PAMI 1991) of the estimated positions onto the ground-truth ones,
//   p_aligned = s * R * p_est + t (s = 1 for SE3);
// - ATE: |p_gt - p_aligned| per associated pose (evo_ape's translation_part);
// - RPE: E = (T_gt_i^-1 T_gt_j)^-1 (T_est_i^-1 T_est_j) over consecutive pairs (i, i+delta)
//   of the associated, aligned poses (evo_rpe's default pairs); translation |t(E)| in metres,
//   rotation angle(R(E)) in degrees.
// The path length used for "% of path" is the length of the associated ground-truth poses.
//
// Ownership: plain values in and out. Threads: any; no shared state. Allocates: offline tool
// (eval, replay summaries), never called per frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/trajectory.h"

namespace rdslam {

enum class Alignment { kNone, kSe3, kSim3 };

const char* to_string(Alignment a);
// Parses "none" | "se3" | "sim3"; returns false on anything else.
bool parse_alignment(const std::string& text, Alignment& out);

// Pairs of indices (ground truth, estimate).
using IndexPairs = std::vector<std::pair<size_t, size_t>>;

// Nearest-stamp association as in evo's sync.associate_trajectories (see above).
IndexPairs associate_by_time(const Trajectory& gt, const Trajectory& est, int64_t max_diff_ns);
// Pairs (i, i) for i < min(gt.size(), est.size()).
IndexPairs associate_by_index(const Trajectory& gt, const Trajectory& est);

// p_dst ~= scale * R * p_src + t.
struct Sim3Transform {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double scale = 1.0;
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return scale * (R * p) + t; }
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// Least-squares alignment of `src` onto `dst` (same size). kNone returns the identity.
// Returns false (and the identity) when fewer than 3 points are given or the points are
// degenerate (covariance rank < 2, e.g. all equal or all on one point), as evo refuses too.
bool umeyama_align(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                   Alignment mode, Sim3Transform& out);

struct ErrorStats {
  size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;  // mean of the two middle values for an even count (numpy.median)
  double max = 0.0;
  double min = 0.0;
  double std = 0.0;  // population standard deviation (numpy.std)
};
ErrorStats compute_stats(const std::vector<double>& errors);

struct EvalParams {
  Alignment align = Alignment::kSim3;  // monocular SLAM has no metric scale: Sim3 by default
  bool by_index = false;               // KITTI: associate by index instead of by time
  int64_t max_diff_ns = 10000000;      // 10 ms, evo's default max_diff
  int rpe_delta = 1;                   // RPE pair distance in associated poses (frames)
};

struct EvalResult {
  bool ok = false;
  std::string error;  // why !ok: no association, too few poses, degenerate alignment
  size_t gt_poses = 0;
  size_t est_poses = 0;
  IndexPairs pairs;
  Sim3Transform alignment;
  double gt_path_length_m = 0.0;  // over the associated ground-truth poses
  // Per associated pose: ground-truth stamp, aligned estimate position and ATE error.
  std::vector<int64_t> stamps_ns;
  std::vector<Eigen::Vector3d> gt_positions;
  std::vector<Eigen::Vector3d> est_positions_aligned;
  std::vector<double> ate_errors_m;
  ErrorStats ate_m;
  ErrorStats ate_pct_path;  // ate_m scaled by 100 / gt_path_length_m (0 if the path is 0)
  ErrorStats rpe_trans_m;
  ErrorStats rpe_rot_deg;
};

EvalResult evaluate_trajectories(const Trajectory& gt, const Trajectory& est,
                                 const EvalParams& params);

}  // namespace rdslam
