// PNG plots of trajectories drawn with OpenCV (no plotting library on the robot): a top view
// of one or more trajectories with metric axes, grid, scale bar and legend, and an optional
// lower panel with a curve over time (e.g. the ATE per pose). Used by `rdslam eval --plot`
// and meant for `rdslam replay --plot`.
//
// Ownership: values in, an image out. Threads: any; allocates (offline tool, never per frame).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rdslam {

struct PlotTrack {
  std::string label;  // legend text; empty: not in the legend
  cv::Scalar color;   // BGR
  std::vector<Eigen::Vector3d> positions;
  int thickness = 2;
};

struct PlotCurve {
  std::string label;  // legend text; empty: not in the legend
  cv::Scalar color;
  std::vector<double> t_s;     // x: time in seconds
  std::vector<double> values;  // y, same size as t_s
};

struct TrajectoryPlot {
  std::string title;
  // Top view with equal scale on both axes; labels name the world axes shown.
  std::vector<PlotTrack> tracks;
  // World axis pointing up or down (0 x, 1 y, 2 z), dropped from the top view; -1: the axis
  // with the smallest extent. KITTI camera worlds: 1 (y down); EuRoC/TUM mocap worlds: 2.
  int up_axis = -1;
  bool up_is_negative = false;  // true when up is -up_axis (KITTI: y points down)
  // Lower panel; omitted when `curves` is empty.
  std::vector<PlotCurve> curves;
  std::string curve_title;
  std::string curve_y_label = "error [m]";
  int width_px = 1200;
};

cv::Mat render_trajectory_plot(const TrajectoryPlot& plot);

// Renders and writes a PNG. Throws std::runtime_error naming the path when it cannot be
// written (CLI boundary).
void write_trajectory_plot(const TrajectoryPlot& plot, const std::string& path);

}  // namespace rdslam
