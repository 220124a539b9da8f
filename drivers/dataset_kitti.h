// KITTI odometry sequences (Geiger et al., CVPR 2012), left grey camera 0:
//   DIR/image_0/*.png (or image_l/)  rectified images, sorted by name
//   DIR/times.txt                    optional: one time in seconds per image; without it
//                                    frames are 1/rate_hz apart (KITTI records at 10 Hz)
//   DIR/calib.txt                    P0 (3x4, "P0: ..." or a bare first line of 12 numbers):
//                                    fx = P0[0,0], fy = P0[1,1], cx = P0[0,2], cy = P0[1,2];
//                                    rectified, so no distortion
//   DIR/poses.txt, or DIR/../../poses/<DIR name>.txt (the official layout
//                                    dataset/sequences/06 + dataset/poses/06.txt): optional
//                                    ground truth, 3x4 T_world_cam0 per image.
//
// Threads: start-up only. Throws std::runtime_error naming file (and line) on bad input.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "drivers/replay_source.h"

namespace rdslam {

// The image folder (image_0 or image_l) under `dir`, "" when there is none.
std::string kitti_image_dir(const std::string& dir);
bool looks_like_kitti(const std::string& dir);
// P0 of calib.txt as a distortion-free pinhole camera of the given image size.
CameraModel read_kitti_calib(const std::string& path, int width, int height);
// times.txt: seconds (KITTI writes e.g. "1.036822e-01") -> ns.
std::vector<int64_t> read_kitti_times(const std::string& path);
std::unique_ptr<ReplaySource> open_kitti_source(const std::string& uri, const std::string& dir,
                                                double rate_hz, double speed);

}  // namespace rdslam
