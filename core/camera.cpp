#include "core/camera.h"

#include <opencv2/calib3d.hpp>

namespace rdslam {

void CameraModel::visit(ParamVisitor& v) {
  v.field("model", model, {"pinhole-radtan", "pinhole-equidistant"}, "distortion model");
  v.field("width", width, 16, 8192, "image width in pixels");
  v.field("height", height, 16, 8192, "image height in pixels");
  v.field("fx", fx, 1.0, 1e5, "focal length x in pixels");
  v.field("fy", fy, 1.0, 1e5, "focal length y in pixels");
  v.field("cx", cx, -1e5, 1e5, "principal point x in pixels");
  v.field("cy", cy, -1e5, 1e5, "principal point y in pixels");
  v.field("k1", k1, -10.0, 10.0, "radial distortion k1");
  v.field("k2", k2, -10.0, 10.0, "radial distortion k2");
  v.field("p1", p1, -10.0, 10.0, "tangential distortion p1 (radtan only)");
  v.field("p2", p2, -10.0, 10.0, "tangential distortion p2 (radtan only)");
  v.field("k3", k3, -10.0, 10.0, "radial distortion k3");
  v.field("k4", k4, -10.0, 10.0, "distortion k4 (equidistant only)");
}

bool CameraModel::has_distortion() const {
  return k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0 || k3 != 0.0 || k4 != 0.0;
}

Eigen::Matrix3d CameraModel::K_eigen() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

cv::Mat CameraModel::dist_coeffs() const {
  if (is_equidistant()) return (cv::Mat_<double>(4, 1) << k1, k2, k3, k4);
  return (cv::Mat_<double>(5, 1) << k1, k2, p1, p2, k3);
}

std::string CameraModel::validate() const {
  if (cx < 0 || cx > width) {
    return "camera.cx: value " + std::to_string(cx) + " lies outside the image; allowed [0, " +
           std::to_string(width) + "] (camera.width)";
  }
  if (cy < 0 || cy > height) {
    return "camera.cy: value " + std::to_string(cy) + " lies outside the image; allowed [0, " +
           std::to_string(height) + "] (camera.height)";
  }
  if (is_equidistant() && (p1 != 0.0 || p2 != 0.0)) {
    return "camera.p1/camera.p2: tangential terms are not part of model pinhole-equidistant; "
           "allowed 0";
  }
  if (!is_equidistant() && k4 != 0.0) {
    return "camera.k4: only used by model pinhole-equidistant; allowed 0 for pinhole-radtan";
  }
  return {};
}

void CameraModel::undistort_points(const std::vector<cv::Point2f>& in,
                                   std::vector<cv::Point2f>& out) const {
  if (!has_distortion() || in.empty()) {
    out = in;
    return;
  }
  if (is_equidistant()) {
    cv::fisheye::undistortPoints(in, out, K(), dist_coeffs(), cv::noArray(), K());
  } else {
    cv::undistortPoints(in, out, K(), dist_coeffs(), cv::noArray(), K());
  }
}

}  // namespace rdslam
