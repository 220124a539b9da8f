// Pinhole camera with radial-tangential (OpenCV k1 k2 p1 p2 k3) or equidistant (fisheye
// k1..k4, stored in k1 k2 p1 p2 order as k1 k2 k3 k4) distortion.
//
// Ownership: plain value type. Threads: immutable after start-up; any thread may read it.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

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
  // Undistort pixel coordinates to ideal pinhole pixels (same K). Allocates: start-up/tests.
  void undistort_points(const std::vector<cv::Point2f>& in, std::vector<cv::Point2f>& out) const;
};

}  // namespace rdslam
