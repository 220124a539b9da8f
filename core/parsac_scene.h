// The synthetic experiment of RDSLAM Sec. 5 (Fig. 6, Tables 1 and 2): a static background of
// 200 points, a rigidly moving object of 300 points and 500 randomly moving points, observed by
// a moving camera (640x480) for 100 frames with 1 px Gaussian noise; the camera and the object
// undergo different motions. Each frame is a set of 2D-3D correspondences (pixel, map point):
//  - static points: the map point is the true world point;
//  - object points: the map point is where the object was when it was mapped, so the points
//    are consistent with the "object motion" T_cam_world * T_world_obj(t) * T_world_obj(map)^-1
//    (30% of the data: plain RANSAC prefers it over the camera's 20%);
//  - random points: each moves on its own smooth image trajectory and is matched to an
//    unrelated map point (consistent with no pose).
// Static points that leave the image are replaced by new ones (as a tracker adds features),
// so every frame has 200 + 300 + 500 correspondences.
//
// Ownership: plain values. Threads: any. Allocates (test and benchmark tool, not real time).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "core/camera.h"

namespace rdslam {

struct ParsacSceneParams {
  int frames = 100;
  int static_points = 200;
  int object_points = 300;
  int random_points = 500;
  double noise_px = 1.0;
  // Random points: 0 spreads them uniformly over the image; k > 0 groups them in k moving
  // blobs (the paper's "dynamic foreground points may aggregate in a few small textured areas").
  int random_clusters = 0;
  double cluster_sigma_px = 60.0;
  uint64_t seed = 1;
};

struct ParsacFrame {
  std::vector<Eigen::Vector2d> pixels;   // observations (undistorted pixels)
  std::vector<Eigen::Vector3d> p_world;  // matched map points
  std::vector<uint8_t> label;            // 0 static, 1 object, 2 random
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();  // ground-truth camera
  Eigen::Isometry3d T_object = Eigen::Isometry3d::Identity();     // pose that fits the object
  double mean_static_depth_m = 0.0;
};

// Camera used by the experiment: 640x480, f = 525 px, principal point at the centre.
CameraModel parsac_scene_camera();
std::vector<ParsacFrame> make_parsac_scene(const ParsacSceneParams& params);

// Success criterion of the benchmark: rotation error below `max_rot_deg` and camera-centre
// error below `max_centre_frac` times the mean static depth.
bool pose_matches(const Eigen::Isometry3d& T_est, const Eigen::Isometry3d& T_true,
                  double mean_depth_m, double max_rot_deg = 1.0, double max_centre_frac = 0.02);

}  // namespace rdslam
