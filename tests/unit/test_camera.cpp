// CameraModel's lens (core/camera.h): distort() is OpenCV's model (cv::projectPoints,
// cv::fisheye::projectPoints), undistort() its inverse, distort_jacobian() its derivative.
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>

#include "core/camera.h"

namespace rdslam {
namespace {

CameraModel radtan() {
  CameraModel c;
  c.k1 = -0.3;
  c.k2 = 0.1;
  c.p1 = 0.001;
  c.p2 = -0.0015;
  c.k3 = 0.01;
  return c;
}

CameraModel fisheye() {
  CameraModel c;
  c.model = "pinhole-equidistant";
  c.fx = c.fy = 305;
  c.k1 = 0.02;
  c.k2 = -0.01;
  c.k3 = 0.003;
  c.k4 = -0.0005;
  return c;
}

// Camera-frame points spread over the view (up to 70 degrees off the axis).
std::vector<cv::Point3d> points() {
  std::vector<cv::Point3d> p;
  for (double ax = -70; ax <= 70; ax += 10) {
    for (double ay = -60; ay <= 60; ay += 15) {
      const double x = std::tan(ax * M_PI / 180), y = std::tan(ay * M_PI / 180);
      p.emplace_back(x * 2.0, y * 2.0, 2.0);
    }
  }
  return p;
}

void expect_matches_opencv(const CameraModel& cam) {
  const std::vector<cv::Point3d> pts = points();
  std::vector<cv::Point2d> cv_px;
  const cv::Mat zero = cv::Mat::zeros(3, 1, CV_64F);
  if (cam.is_equidistant()) {
    cv::fisheye::projectPoints(pts, cv_px, zero, zero, cam.K(), cam.dist_coeffs());
  } else {
    cv::projectPoints(pts, zero, zero, cam.K(), cam.dist_coeffs(), cv_px);
  }
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector2d px = cam.project(Eigen::Vector3d(pts[i].x, pts[i].y, pts[i].z));
    EXPECT_NEAR(px.x(), cv_px[i].x, 1e-6) << cam.model << " point " << i;
    EXPECT_NEAR(px.y(), cv_px[i].y, 1e-6) << cam.model << " point " << i;
  }
}

TEST(Camera, DistortionIsOpenCvsModel) {
  expect_matches_opencv(radtan());
  expect_matches_opencv(fisheye());
}

TEST(Camera, UndistortInvertsDistortOverTheImage) {
  for (const CameraModel& cam : {radtan(), fisheye()}) {
    double worst = 0;
    for (int y = 0; y < cam.height; y += 7) {
      for (int x = 0; x < cam.width; x += 7) {
        Eigen::Vector2d ideal;
        ASSERT_TRUE(cam.undistort(Eigen::Vector2d(x, y), &ideal))
            << cam.model << " " << x << "," << y;
        worst = std::max(worst, (cam.distort(ideal) - Eigen::Vector2d(x, y)).norm());
      }
    }
    EXPECT_LT(worst, 1e-6) << cam.model;
  }
  // The equidistant corner lies further out in ideal pixels than in the image (tan theta >
  // theta): a fisheye's ideal image is wider than its raw one.
  Eigen::Vector2d corner;
  ASSERT_TRUE(fisheye().undistort(Eigen::Vector2d(0, 0), &corner));
  EXPECT_LT(corner.x(), -300);
}

TEST(Camera, JacobianIsTheDerivativeOfDistort) {
  for (const CameraModel& cam : {radtan(), fisheye()}) {
    for (const Eigen::Vector2d& ideal : {Eigen::Vector2d(319.5, 239.5), Eigen::Vector2d(40, 30),
                                         Eigen::Vector2d(700, 500), Eigen::Vector2d(-200, 100)}) {
      const Eigen::Matrix2d J = cam.distort_jacobian(ideal);
      const double h = 1e-4;
      for (int k = 0; k < 2; ++k) {
        const Eigen::Vector2d e = Eigen::Vector2d::Unit(k) * h;
        const Eigen::Vector2d num = (cam.distort(ideal + e) - cam.distort(ideal - e)) / (2 * h);
        EXPECT_NEAR(J(0, k), num.x(), 1e-6) << cam.model << " at " << ideal.transpose();
        EXPECT_NEAR(J(1, k), num.y(), 1e-6) << cam.model << " at " << ideal.transpose();
      }
    }
  }
}

// What the camera sees is decided through the lens: an ideal pixel far outside the ideal
// rectangle is in view when its raw pixel is in the image, and an ideal pixel inside the
// rectangle is not when the lens puts it outside.
TEST(Camera, InViewThroughTheLensNotTheIdealRectangle) {
  CameraModel pin;
  EXPECT_TRUE(pin.ideal_in_image({0, 0}));
  EXPECT_TRUE(pin.ideal_in_image({639.9, 479.9}));
  EXPECT_FALSE(pin.ideal_in_image({640, 100}));
  EXPECT_FALSE(pin.ideal_in_image({-0.1, 100}));
  const cv::Rect2d pe = pin.ideal_extent();
  EXPECT_EQ(pe, cv::Rect2d(0, 0, 640, 480));
  for (const CameraModel& cam : {radtan(), fisheye()}) {
    // The raw image corner (1, 1), seen through the lens, is in view wherever its ideal pixel is.
    Eigen::Vector2d corner;
    ASSERT_TRUE(cam.undistort({1, 1}, &corner)) << cam.model;
    EXPECT_TRUE(cam.ideal_in_image(corner)) << cam.model;
    // Just outside the raw image is out of view.
    Eigen::Vector2d out;
    ASSERT_TRUE(cam.undistort({-1.5, 240}, &out)) << cam.model;
    EXPECT_FALSE(cam.ideal_in_image(out)) << cam.model;
    // The extent holds the ideal pixels of the whole border.
    const cv::Rect2d e = cam.ideal_extent();
    EXPECT_LE(e.x, corner.x()) << cam.model;
    EXPECT_LE(e.y, corner.y()) << cam.model;
  }
  // The fisheye's corner lies hundreds of pixels outside the ideal rectangle, yet in view.
  Eigen::Vector2d corner;
  ASSERT_TRUE(fisheye().undistort({1, 1}, &corner));
  EXPECT_LT(corner.x(), -300);
  EXPECT_TRUE(fisheye().ideal_in_image(corner));
  // Pincushion (k1 > 0): the ideal rectangle's corner maps outside the image: not in view.
  CameraModel pc;
  pc.k1 = 0.3;
  EXPECT_FALSE(pc.ideal_in_image({1, 1}));
  EXPECT_TRUE(pc.ideal_in_image({319.5, 239.5}));
}

TEST(Camera, EquidistantIsADistortionEvenWithZeroCoefficients) {
  CameraModel c;
  EXPECT_FALSE(c.has_distortion());
  c.model = "pinhole-equidistant";
  EXPECT_TRUE(c.has_distortion());
  // 60 degrees off the axis: raw radius f * pi / 3, ideal radius f * tan(60 deg).
  const Eigen::Vector2d raw = c.project(Eigen::Vector3d(std::tan(M_PI / 3), 0, 1));
  EXPECT_NEAR(raw.x() - c.cx, c.fx * M_PI / 3, 1e-9);
  // A ray 90 degrees off the axis has no ideal pixel.
  Eigen::Vector2d ideal;
  EXPECT_FALSE(c.undistort(Eigen::Vector2d(c.cx + c.fx * M_PI / 2 + 1, c.cy), &ideal));
}

}  // namespace
}  // namespace rdslam
