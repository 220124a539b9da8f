// Timestamped 6-DoF trajectories (camera poses T_world_cam) and their file formats.
//
// Ownership: plain value types. Threads: any; no shared state.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace rdslam {

struct StampedPose {
  int64_t stamp_ns = 0;                  // time of the image, ns (dataset clock or CLOCK_MONOTONIC)
  Eigen::Vector3d p_world_cam{0, 0, 0};  // camera centre in world
  Eigen::Quaterniond q_world_cam{1, 0, 0, 0};  // rotation cam -> world
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

using Trajectory = std::vector<StampedPose, Eigen::aligned_allocator<StampedPose>>;

enum class TrajectoryFormat { kTum, kEuroc, kKitti };

// Readers. Throw std::runtime_error with file name and line number on malformed input
// (start-up/config boundary). KITTI poses carry no time: stamp_ns is the row index times
// `kitti_period_ns` (default 0.1 s) unless timestamps are given separately.
Trajectory read_trajectory(const std::string& path, TrajectoryFormat format,
                           int64_t kitti_period_ns = 100000000);
// Guess the format from content: 8 numbers per line -> TUM, 12 -> KITTI, CSV with >= 8 -> EuRoC.
TrajectoryFormat detect_trajectory_format(const std::string& path);
// TUM format: "t tx ty tz qx qy qz qw" with t in seconds (9 decimals).
void write_trajectory_tum(const std::string& path, const Trajectory& traj);

}  // namespace rdslam
