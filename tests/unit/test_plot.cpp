// Trajectory plots: the drawing lands where the data is, the top view keeps equal scale and
// a right-handed orientation, and degenerate input (no points, one point, NaN) still gives an
// image.
#include "firmware_app/plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

using rdslam::PlotTrack;
using rdslam::TrajectoryPlot;

namespace {

const cv::Scalar kRed(0, 0, 255);

// Pixels of exactly the track colour (antialiasing leaves the line's core pure).
cv::Mat mask_of(const cv::Mat& img, const cv::Scalar& c) {
  cv::Mat m;
  cv::inRange(img, c, c, m);
  return m;
}

}  // namespace

TEST(Plot, TopViewHasEqualScale) {
  // A 4 m x 1 m rectangle in the x-y plane (z up): drawn 4 times wider than tall.
  TrajectoryPlot plot;
  plot.title = "rectangle";
  plot.tracks.push_back({"", kRed, {{0, 0, 0}, {4, 0, 0}, {4, 1, 0}, {0, 1, 0}, {0, 0, 0}}, 3});
  const cv::Mat img = rdslam::render_trajectory_plot(plot);
  EXPECT_EQ(img.cols, 1200);
  const cv::Rect box = cv::boundingRect(mask_of(img, kRed));
  ASSERT_GT(box.height, 10);
  EXPECT_NEAR(static_cast<double>(box.width) / box.height, 4.0, 0.25)
      << box.width << "x" << box.height;
}

TEST(Plot, TopViewIsSeenFromAbove) {
  // z-up world: a point at +y must appear above (smaller row) one at -y when x is horizontal.
  TrajectoryPlot plot;
  plot.up_axis = 2;
  plot.tracks.push_back({"", kRed, {{0, 1, 0}, {10, 1, 0}}, 3});
  plot.tracks.push_back({"", cv::Scalar(255, 0, 0), {{0, -1, 0}, {10, -1, 0}}, 3});
  cv::Mat img = rdslam::render_trajectory_plot(plot);
  const int row_a = cv::boundingRect(mask_of(img, kRed)).y;
  const int row_b = cv::boundingRect(mask_of(img, cv::Scalar(255, 0, 0))).y;
  EXPECT_LT(row_a, row_b);

  // KITTI camera world (y down, z forward, x right): seen from above with z to the right,
  // x points down the image (right-handed), so +x must appear BELOW -x.
  TrajectoryPlot kitti;
  kitti.up_axis = 1;
  kitti.up_is_negative = true;
  kitti.tracks.push_back({"", kRed, {{1, 0, 0}, {1, 0, 10}}, 3});
  kitti.tracks.push_back({"", cv::Scalar(255, 0, 0), {{-1, 0, 0}, {-1, 0, 10}}, 3});
  img = rdslam::render_trajectory_plot(kitti);
  const cv::Rect a = cv::boundingRect(mask_of(img, kRed));
  const cv::Rect b = cv::boundingRect(mask_of(img, cv::Scalar(255, 0, 0)));
  EXPECT_GT(a.width, 5 * a.height);  // z (10 m) is the horizontal axis
  EXPECT_GT(a.y, b.y);
}

TEST(Plot, DegenerateInputStillRenders) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  TrajectoryPlot plot;
  EXPECT_FALSE(rdslam::render_trajectory_plot(plot).empty());  // nothing at all
  plot.tracks.push_back({"", kRed, {{1, 2, 3}}, 2});
  plot.tracks.push_back({"nan", cv::Scalar(0, 255, 0), {{nan, 0, 0}, {0, nan, 0}}, 2});
  plot.curves.push_back({"flat", cv::Scalar(0, 0, 200), {0, 0, 0}, {0, 0, 0}});
  plot.curves.push_back({"nan", cv::Scalar(0, 0, 200), {nan, 1}, {1, nan}});
  const cv::Mat img = rdslam::render_trajectory_plot(plot);
  ASSERT_FALSE(img.empty());
  EXPECT_GT(cv::countNonZero(mask_of(img, kRed)), 0);  // the single point is drawn
}

TEST(Plot, WriteFailsWithThePath) {
  TrajectoryPlot plot;
  try {
    rdslam::write_trajectory_plot(plot, "/nonexistent-dir/plot.png");
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/plot.png"), std::string::npos)
        << e.what();
  }
}
