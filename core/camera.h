// Pinhole camera with radial-tangential (OpenCV k1 k2 p1 p2 k3) or equidistant (fisheye
// k1..k4, stored in k1 k2 p1 p2 order as k1 k2 k3 k4) distortion.
//
// Two kinds of pixel: raw pixels (the image as the lens forms it) and ideal pixels (the same
// K without distortion: the pinhole geometry the tracker and mapper work in). distort() maps
// ideal to raw, undistort() raw to ideal, both with OpenCV's models (cv::projectPoints,
// cv::fisheye::projectPoints); the equidistant model is a distortion even with k1..k4 = 0
// (raw radius f theta, ideal radius f tan theta).
//
// Ownership: plain value type. Threads: immutable after start-up; any thread may read it.
// distort, project, distort_jacobian and undistort allocate nothing (real-time loops may call
// them); undistort_points allocates (start-up and tests).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/params.h"

namespace rdslam {

struct CameraModel {
  std::string model = "pinhole-radtan";  // pinhole-radtan | pinhole-equidistant
  int width = 640;
  int height = 480;
  double fx = 525.0;
  double fy = 525.0;
  double cx = 319.5;
  double cy = 239.5;
  // Distortion. radtan: k1 k2 p1 p2 k3 (OpenCV order). equidistant: k1 k2 k3 k4 (p1, p2 unused).
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;
  double k3 = 0.0;
  double k4 = 0.0;

  void visit(ParamVisitor& v);
  bool is_equidistant() const { return model == "pinhole-equidistant"; }
  bool has_distortion() const;
  cv::Matx33d K() const { return cv::Matx33d(fx, 0, cx, 0, fy, cy, 0, 0, 1); }
  Eigen::Matrix3d K_eigen() const;
  // Distortion coefficients in the layout OpenCV expects for this model.
  cv::Mat dist_coeffs() const;
  // Cross-field validation; returns an empty string when valid, otherwise a message that
  // names the key. Field ranges are checked by the loader.
  std::string validate() const;
  // Ideal pixel -> raw pixel.
  Eigen::Vector2d distort(const Eigen::Vector2d& ideal) const;
  // Camera-frame point (z > 0) -> raw pixel.
  Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const;
  // d raw / d ideal at an ideal pixel: how a small window around it is stretched in the image.
  Eigen::Matrix2d distort_jacobian(const Eigen::Vector2d& ideal) const;
  // Whether the camera sees an ideal pixel: its raw pixel lies inside the image and the lens
  // maps its neighbourhood without folding over (distort_jacobian has a positive
  // determinant). Without distortion, the ideal pixel lies in [0, width) x [0, height).
  // Projection-guided matching uses this, not the ideal rectangle: a lens shows ideal pixels
  // far outside it (a 150-degree fisheye's corner is about 900 px out). Allocates nothing.
  bool ideal_in_image(const Eigen::Vector2d& ideal) const;
  // The rectangle holding the ideal pixels of every raw pixel of the image (the undistorted
  // image border's bounding box, joined with [0, width] x [0, height] and clipped to
  // [-2 width, 3 width] x [-2 height, 3 height]); (0, 0, width, height) without distortion.
  // Walks the border: start-up only.
  cv::Rect2d ideal_extent() const;
  // Raw pixel -> ideal pixel by Newton's method on distort() (|distort(ideal) - raw| below
  // 1e-9 px). False when it does not converge, or (equidistant) the ray lies 90 degrees or
  // more off the optical axis and has no ideal pixel.
  bool undistort(const Eigen::Vector2d& raw, Eigen::Vector2d* ideal) const;
  // undistort() of each point (a point without an ideal pixel keeps its raw coordinates).
  // Allocates: start-up/tests.
  void undistort_points(const std::vector<cv::Point2f>& in, std::vector<cv::Point2f>& out) const;

 private:
  // Distortion in normalised coordinates (x/z, y/z), with its Jacobian when j != nullptr.
  Eigen::Vector2d distort_normalised(const Eigen::Vector2d& q, Eigen::Matrix2d* j) const;
};

}  // namespace rdslam
