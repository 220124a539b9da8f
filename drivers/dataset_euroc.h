// EuRoC MAV / ASL dataset folders (Burri et al., IJRR 2016), monocular: camera cam0.
//   DIR/mav0/cam0/data.csv     "#timestamp [ns],filename"; images in DIR/mav0/cam0/data/
//   DIR/mav0/cam0/sensor.yaml  intrinsics (pinhole; radial-tangential or equidistant) and
//                              T_BS: the camera (sensor S) pose in the body/IMU frame B,
//                              i.e. T_body_cam (maps camera coordinates to body coordinates)
//   DIR/mav0/state_groundtruth_estimate0/data.csv  optional ground truth of the BODY:
//                              T_world_body; the source converts it to the camera:
//                              T_world_cam = T_world_body * T_body_cam.
// DIR may also be the mav0 folder itself.
//
// Threads: start-up only. Throws std::runtime_error naming file (and line) on bad input.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "drivers/replay_source.h"

namespace rdslam {

struct EurocCameraInfo {
  CameraModel camera;
  Eigen::Isometry3d T_body_cam = Eigen::Isometry3d::Identity();
  double rate_hz = 0.0;
};

// The mav0 folder under `dir` ("" when there is none): dir/mav0 or dir itself.
std::string euroc_mav0_dir(const std::string& dir);
bool looks_like_euroc(const std::string& dir);
// Parses an ASL sensor.yaml of a camera (the "%YAML:1.0" first line is accepted).
EurocCameraInfo read_euroc_camera_yaml(const std::string& path);
// T_world_cam_i = T_world_body_i * T_body_cam for every pose.
Trajectory body_to_camera(const Trajectory& T_world_body, const Eigen::Isometry3d& T_body_cam);
std::unique_ptr<ReplaySource> open_euroc_source(const std::string& uri, const std::string& dir,
                                                double speed);

}  // namespace rdslam
