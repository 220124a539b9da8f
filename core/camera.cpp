#include "core/camera.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

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
  // Equidistant: raw radius f theta, ideal f tan theta, whatever k1..k4 say.
  return is_equidistant() || k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0 || k3 != 0.0 ||
         k4 != 0.0;
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

Eigen::Vector2d CameraModel::distort_normalised(const Eigen::Vector2d& q,
                                                Eigen::Matrix2d* j) const {
  const double x = q.x(), y = q.y(), r2 = x * x + y * y;
  if (is_equidistant()) {
    // cv::fisheye: theta = atan(r), theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8),
    // distorted = q theta_d / r.
    const double r = std::sqrt(r2);
    if (r < 1e-12) {
      if (j != nullptr) j->setIdentity();
      return q;
    }
    const double th = std::atan(r), t2 = th * th;
    const double poly = 1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
    const double th_d = th * poly;
    const double s = th_d / r;
    if (j != nullptr) {
      // d theta_d / d theta, d theta / d r = 1 / (1 + r^2); d s / d r = (theta_d' r - theta_d) /
      // r^2.
      const double dth_d = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)));
      const double ds_dr = (dth_d / (1 + r2) * r - th_d) / r2;
      // J = s I + (ds/dr / r) q q^T
      *j = s * Eigen::Matrix2d::Identity() + (ds_dr / r) * q * q.transpose();
    }
    return s * q;
  }
  // cv::projectPoints' radial-tangential model (k1 k2 p1 p2 k3).
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  if (j != nullptr) {
    const double dr = k1 + r2 * (2 * k2 + r2 * 3 * k3);  // d radial / d r2
    (*j)(0, 0) = radial + 2 * x * x * dr + 2 * p1 * y + 6 * p2 * x;
    (*j)(0, 1) = 2 * x * y * dr + 2 * p1 * x + 2 * p2 * y;
    (*j)(1, 0) = 2 * x * y * dr + 2 * p1 * x + 2 * p2 * y;
    (*j)(1, 1) = radial + 2 * y * y * dr + 6 * p1 * y + 2 * p2 * x;
  }
  return {x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
          y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y};
}

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& ideal) const {
  if (!has_distortion()) return ideal;
  const Eigen::Vector2d d =
      distort_normalised({(ideal.x() - cx) / fx, (ideal.y() - cy) / fy}, nullptr);
  return {fx * d.x() + cx, fy * d.y() + cy};
}

Eigen::Vector2d CameraModel::project(const Eigen::Vector3d& p_cam) const {
  const double iz = 1.0 / p_cam.z();
  const Eigen::Vector2d ideal(fx * p_cam.x() * iz + cx, fy * p_cam.y() * iz + cy);
  return has_distortion() ? distort(ideal) : ideal;
}

Eigen::Matrix2d CameraModel::distort_jacobian(const Eigen::Vector2d& ideal) const {
  if (!has_distortion()) return Eigen::Matrix2d::Identity();
  Eigen::Matrix2d j;
  distort_normalised({(ideal.x() - cx) / fx, (ideal.y() - cy) / fy}, &j);
  // Pixels: diag(fx, fy) J diag(1/fx, 1/fy).
  j(0, 1) *= fx / fy;
  j(1, 0) *= fy / fx;
  return j;
}

bool CameraModel::undistort(const Eigen::Vector2d& raw, Eigen::Vector2d* ideal) const {
  if (!has_distortion()) {
    *ideal = raw;
    return true;
  }
  const Eigen::Vector2d target((raw.x() - cx) / fx, (raw.y() - cy) / fy);
  Eigen::Vector2d q = target;
  if (is_equidistant()) {
    // Radial: solve theta_d(theta) = |target| for theta (Newton from theta = theta_d), then
    // the ideal radius is tan(theta).
    const double rd = target.norm();
    if (rd < 1e-12) {
      *ideal = raw;
      return true;
    }
    double th = rd;
    bool ok = false;
    for (int it = 0; it < 50; ++it) {
      const double t2 = th * th;
      const double f = th * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - rd;
      const double df = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)));
      if (!(std::abs(df) > 1e-12)) return false;
      const double step = f / df;
      th -= step;
      if (std::abs(step) < 1e-14) {
        ok = true;
        break;
      }
    }
    if (!ok || !(th > 0) || th >= M_PI / 2 - 1e-9) return false;
    q = target * (std::tan(th) / rd);
  } else {
    bool ok = false;
    for (int it = 0; it < 100; ++it) {
      Eigen::Matrix2d j;
      const Eigen::Vector2d e = distort_normalised(q, &j) - target;
      const double det = j.determinant();
      if (!(std::abs(det) > 1e-12)) return false;
      const Eigen::Vector2d step = j.inverse() * e;
      // Damped: a full step may leave the region where the model is monotonic.
      const double n = step.norm(), cap = 0.25 * (1.0 + q.norm());
      q -= n > cap ? step * (cap / n) : step;
      if (n < 1e-14 * (1.0 + q.norm())) {
        ok = true;
        break;
      }
    }
    if (!ok) return false;
  }
  *ideal = Eigen::Vector2d(fx * q.x() + cx, fy * q.y() + cy);
  return std::isfinite(ideal->x()) && std::isfinite(ideal->y());
}

bool CameraModel::ideal_in_image(const Eigen::Vector2d& ideal) const {
  if (!has_distortion()) {
    return ideal.x() >= 0 && ideal.y() >= 0 && ideal.x() < width && ideal.y() < height;
  }
  if (!std::isfinite(ideal.x()) || !std::isfinite(ideal.y())) return false;
  const Eigen::Vector2d raw = distort(ideal);
  if (!(raw.x() >= 0 && raw.y() >= 0 && raw.x() < width && raw.y() < height)) return false;
  return distort_jacobian(ideal).determinant() > 0;
}

cv::Rect2d CameraModel::ideal_extent() const {
  if (!has_distortion()) return {0.0, 0.0, double(width), double(height)};
  double x0 = 0, y0 = 0, x1 = width, y1 = height;
  auto add = [&](double x, double y) {
    Eigen::Vector2d u;
    if (!undistort({x, y}, &u)) return;
    x0 = std::min(x0, u.x());
    y0 = std::min(y0, u.y());
    x1 = std::max(x1, u.x());
    y1 = std::max(y1, u.y());
  };
  for (int x = 0; x < width; ++x) {
    add(x, 0);
    add(x, height - 1);
  }
  for (int y = 0; y < height; ++y) {
    add(0, y);
    add(width - 1, y);
  }
  x0 = std::max(x0, -2.0 * width);
  y0 = std::max(y0, -2.0 * height);
  x1 = std::min(x1, 3.0 * width);
  y1 = std::min(y1, 3.0 * height);
  return {x0, y0, x1 - x0, y1 - y0};
}

void CameraModel::undistort_points(const std::vector<cv::Point2f>& in,
                                   std::vector<cv::Point2f>& out) const {
  out.resize(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    Eigen::Vector2d u;
    out[i] = undistort({in[i].x, in[i].y}, &u) ? cv::Point2f(float(u.x()), float(u.y())) : in[i];
  }
}

}  // namespace rdslam
