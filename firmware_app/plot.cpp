#include "firmware_app/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace rdslam {

namespace {

const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kGrid(225, 225, 225);
const cv::Scalar kWhite(255, 255, 255);
const int kFont = cv::FONT_HERSHEY_SIMPLEX;
const double kFontScale = 0.5;
const char* kAxisNames[3] = {"x", "y", "z"};

// Sub-pixel drawing: OpenCV takes fixed-point coordinates with `shift` fractional bits.
const int kShift = 4;
const double kShiftScale = 16.0;

void text(cv::Mat& img, const std::string& s, cv::Point org, double scale = kFontScale,
          int thickness = 1, const cv::Scalar& color = kBlack) {
  cv::putText(img, s, org, kFont, scale, color, thickness, cv::LINE_AA);
}

cv::Size text_size(const std::string& s, double scale = kFontScale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, scale, thickness, &baseline);
}

// Text centred horizontally on x with its baseline at y.
void text_centered(cv::Mat& img, const std::string& s, int x, int y, double scale = kFontScale,
                   int thickness = 1) {
  text(img, s, {x - text_size(s, scale, thickness).width / 2, y}, scale, thickness);
}

// 1, 2 or 5 times a power of ten, so that `range` holds about `target` steps.
double nice_step(double range, int target) {
  if (!(range > 0.0)) return 1.0;
  const double raw = range / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  return (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0) * mag;
}

std::string tick_label(double v, double step) {
  if (std::fabs(v) < step * 1e-6) v = 0.0;  // no "-0" or "1e-17"
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  char buf[32];
  if (decimals > 4 || std::fabs(v) >= 1e6) {
    std::snprintf(buf, sizeof(buf), "%.3g", v);  // "5e-07" fits the margin, "0.0000005" not
  } else {
    std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  }
  return buf;
}

// A data rectangle [x0, x1] x [y0, y1] drawn into a pixel rectangle.
struct Axes {
  cv::Rect area;
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  bool y_down = false;  // y grows downwards (keeps a top view right-handed, see TopView)
  cv::Point2d map(double x, double y) const {
    const double fy = y_down ? (y - y0) / (y1 - y0) : (y1 - y) / (y1 - y0);
    return {area.x + (x - x0) / (x1 - x0) * area.width, area.y + fy * area.height};
  }
  cv::Point fixed(double x, double y) const {
    const cv::Point2d p = map(x, y);
    return {static_cast<int>(std::lround(p.x * kShiftScale)),
            static_cast<int>(std::lround(p.y * kShiftScale))};
  }
};

// Grid, ticks with labels, frame and axis labels.
void draw_axes(cv::Mat& img, const Axes& ax, const std::string& x_label,
               const std::string& y_label) {
  const double sx = nice_step(ax.x1 - ax.x0, std::max(2, ax.area.width / 110));
  const double sy = nice_step(ax.y1 - ax.y0, std::max(2, ax.area.height / 70));
  const int bottom = ax.area.y + ax.area.height;
  for (double x = std::ceil(ax.x0 / sx) * sx; x <= ax.x1 + 1e-9 * sx; x += sx) {
    const int px = static_cast<int>(std::lround(ax.map(x, 0).x));
    cv::line(img, {px, ax.area.y}, {px, bottom}, kGrid, 1);
    cv::line(img, {px, bottom}, {px, bottom + 5}, kBlack, 1);
    text_centered(img, tick_label(x, sx), px, bottom + 20);
  }
  for (double y = std::ceil(ax.y0 / sy) * sy; y <= ax.y1 + 1e-9 * sy; y += sy) {
    const int py = static_cast<int>(std::lround(ax.map(0, y).y));
    cv::line(img, {ax.area.x, py}, {ax.area.x + ax.area.width, py}, kGrid, 1);
    cv::line(img, {ax.area.x - 5, py}, {ax.area.x, py}, kBlack, 1);
    const std::string s = tick_label(y, sy);
    text(img, s, {ax.area.x - 9 - text_size(s).width, py + 5});
  }
  cv::rectangle(img, ax.area, kBlack, 1);
  text_centered(img, x_label, ax.area.x + ax.area.width / 2, bottom + 42, 0.55);
  text(img, y_label,
       {std::max(4, ax.area.x - 8 - text_size(y_label, 0.55).width / 2), ax.area.y - 7}, 0.55);
}

void draw_polyline(cv::Mat& img, const Axes& ax, const std::vector<cv::Point2d>& pts,
                   const cv::Scalar& color, int thickness) {
  if (pts.empty()) return;
  std::vector<cv::Point> fixed;
  fixed.reserve(pts.size());
  for (const auto& p : pts) fixed.push_back(ax.fixed(p.x, p.y));
  if (fixed.size() == 1) {
    cv::circle(img, fixed[0], 2 * static_cast<int>(kShiftScale), color, cv::FILLED, cv::LINE_AA,
               kShift);
    return;
  }
  cv::polylines(img, fixed, false, color, thickness, cv::LINE_AA, kShift);
}

struct LegendEntry {
  std::string label;
  cv::Scalar color;
  bool marker = false;  // a circle instead of a line sample
};

// A legend row right-aligned above `area` (outside the data, so it never hides a track).
void draw_legend(cv::Mat& img, const cv::Rect& area, const std::vector<LegendEntry>& entries) {
  int x = area.x + area.width;
  const int y = area.y - 12;
  for (auto it = entries.rbegin(); it != entries.rend(); ++it) {
    x -= text_size(it->label).width;
    text(img, it->label, {x, y + 5});
    x -= 8;
    if (it->marker) {
      cv::circle(img, {x - 8, y}, 5, it->color, 2, cv::LINE_AA);
      x -= 16;
    } else {
      cv::line(img, {x - 28, y}, {x, y}, it->color, 3, cv::LINE_AA);
      x -= 28;
    }
    x -= 22;
  }
}

// A bar of a round length in the bottom-left corner of the top view.
void draw_scale_bar(cv::Mat& img, const Axes& ax) {
  const double metres_per_px = (ax.x1 - ax.x0) / ax.area.width;
  const double len = nice_step(metres_per_px * ax.area.width / 5.0, 1);
  const int px = static_cast<int>(std::lround(len / metres_per_px));
  const cv::Point a(ax.area.x + 20, ax.area.y + ax.area.height - 20);
  const cv::Point b(a.x + px, a.y);
  cv::rectangle(img, {a.x - 6, a.y - 24}, {b.x + 6, a.y + 8}, kWhite, cv::FILLED);
  cv::line(img, a, b, kBlack, 3);
  cv::line(img, {a.x, a.y - 6}, {a.x, a.y + 6}, kBlack, 2);
  cv::line(img, {b.x, b.y - 6}, {b.x, b.y + 6}, kBlack, 2);
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g m", len);
  text_centered(img, buf, (a.x + b.x) / 2, a.y - 10);
}

// Which world axes the top view shows and the data extent along them.
struct TopView {
  int h_axis = 0;       // horizontal image axis
  int v_axis = 1;       // vertical image axis
  bool v_down = false;  // the vertical axis grows downwards
  double h_lo = -1, h_hi = 1, v_lo = -1, v_hi = 1;
  // Data height / width with padding, for an equal-scale panel.
  double aspect() const {
    const double pad = 0.06;
    return (std::max(v_hi - v_lo, 1e-3) * (1 + 2 * pad)) /
           (std::max(h_hi - h_lo, 1e-3) * (1 + 2 * pad));
  }
};

TopView plan_top_view(const TrajectoryPlot& plot) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  bool any = false;
  for (const auto& t : plot.tracks) {
    for (const auto& p : t.positions) {
      if (!p.allFinite()) continue;
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      any = true;
    }
  }
  if (!any) {
    lo.setConstant(-1.0);
    hi.setConstant(1.0);
  }
  const Eigen::Vector3d ext = hi - lo;
  // The vertical world axis is dropped: the given one, else the axis of smallest extent.
  // Of the two left, the longer goes horizontal (the image is wider than tall).
  int up = plot.up_axis;
  if (up < 0 || up > 2) {
    up = 2;
    for (int a = 1; a >= 0; --a) {
      if (ext[a] < ext[up]) up = a;
    }
  }
  TopView v;
  v.h_axis = (up + 1) % 3;
  v.v_axis = (up + 2) % 3;
  if (ext[v.v_axis] > ext[v.h_axis]) std::swap(v.h_axis, v.v_axis);
  // Seen from above, screen right x screen up must point at the viewer (+up, or -up for a
  // y-down camera world); otherwise the view would be mirrored and left turns look right.
  const bool cyclic = (v.h_axis + 1) % 3 == v.v_axis;  // e_h x e_v = +e_up
  v.v_down = cyclic == plot.up_is_negative;
  v.h_lo = lo[v.h_axis];
  v.h_hi = hi[v.h_axis];
  v.v_lo = lo[v.v_axis];
  v.v_hi = hi[v.v_axis];
  return v;
}

void draw_top_view(cv::Mat& img, const cv::Rect& area, const TrajectoryPlot& plot,
                   const TopView& view) {
  const int h_axis = view.h_axis;
  const int v_axis = view.v_axis;
  // Equal metric scale on both axes: fit the larger relative extent, centre the other.
  Axes ax;
  ax.area = area;
  const double pad = 0.06;
  double rx = std::max(view.h_hi - view.h_lo, 1e-3) * (1 + 2 * pad);
  double ry = std::max(view.v_hi - view.v_lo, 1e-3) * (1 + 2 * pad);
  const double s = std::min(area.width / rx, area.height / ry);  // px per metre
  rx = area.width / s;
  ry = area.height / s;
  const double cx = 0.5 * (view.h_lo + view.h_hi);
  const double cy = 0.5 * (view.v_lo + view.v_hi);
  ax.x0 = cx - rx / 2;
  ax.x1 = cx + rx / 2;
  ax.y0 = cy - ry / 2;
  ax.y1 = cy + ry / 2;
  ax.y_down = view.v_down;

  draw_axes(img, ax, std::string(kAxisNames[h_axis]) + " [m]",
            std::string(kAxisNames[v_axis]) + (view.v_down ? " [m], growing down" : " [m]"));
  std::vector<LegendEntry> legend;
  for (const auto& t : plot.tracks) {
    std::vector<cv::Point2d> pts;
    pts.reserve(t.positions.size());
    for (const auto& p : t.positions) {
      if (p.allFinite()) pts.emplace_back(p[h_axis], p[v_axis]);
    }
    draw_polyline(img, ax, pts, t.color, t.thickness);
    if (!pts.empty()) {
      const cv::Point2d p0 = ax.map(pts.front().x, pts.front().y);
      cv::circle(img, cv::Point(static_cast<int>(p0.x), static_cast<int>(p0.y)), 6, t.color, 2,
                 cv::LINE_AA);
    }
    if (!t.label.empty()) legend.push_back({t.label, t.color, false});
  }
  if (!plot.tracks.empty()) legend.push_back({"start", cv::Scalar(90, 90, 90), true});
  draw_scale_bar(img, ax);
  draw_legend(img, area, legend);
}

void draw_curves(cv::Mat& img, const cv::Rect& area, const TrajectoryPlot& plot) {
  double t0 = std::numeric_limits<double>::infinity();
  double t1 = -t0;
  double vmax = 0.0;
  for (const auto& c : plot.curves) {
    for (size_t i = 0; i < c.t_s.size() && i < c.values.size(); ++i) {
      if (!std::isfinite(c.t_s[i]) || !std::isfinite(c.values[i])) continue;
      t0 = std::min(t0, c.t_s[i]);
      t1 = std::max(t1, c.t_s[i]);
      vmax = std::max(vmax, c.values[i]);
    }
  }
  if (!(t1 > t0)) {
    t0 = std::isfinite(t0) ? t0 : 0.0;
    t1 = t0 + 1.0;
  }
  Axes ax;
  ax.area = area;
  ax.x0 = t0;
  ax.x1 = t1;
  ax.y0 = 0.0;
  ax.y1 = vmax > 0.0 ? vmax * 1.1 : 1.0;
  draw_axes(img, ax, "time [s]", plot.curve_y_label);
  std::vector<LegendEntry> legend;
  for (const auto& c : plot.curves) {
    std::vector<cv::Point2d> pts;
    for (size_t i = 0; i < c.t_s.size() && i < c.values.size(); ++i) {
      if (std::isfinite(c.t_s[i]) && std::isfinite(c.values[i])) {
        pts.emplace_back(c.t_s[i], c.values[i]);
      }
    }
    draw_polyline(img, ax, pts, c.color, 2);
    if (!c.label.empty()) legend.push_back({c.label, c.color, false});
  }
  draw_legend(img, area, legend);
}

}  // namespace

cv::Mat render_trajectory_plot(const TrajectoryPlot& plot) {
  const int W = std::max(600, plot.width_px);
  const int left = 95, right = 30;
  const int title_lines =
      plot.title.empty()
          ? 0
          : 1 + static_cast<int>(std::count(plot.title.begin(), plot.title.end(), '\n'));
  const int title_h = 24 * title_lines + 10;
  const int legend_h = 34;  // legend row and the vertical axis label above each panel
  const TopView view = plan_top_view(plot);
  const int plot_w = W - left - right;
  // Panel height follows the data's aspect (equal scale), within limits that keep a long
  // straight drive and a square room both readable.
  const int top_h = std::clamp(static_cast<int>(plot_w * view.aspect()), W / 4, W * 3 / 4);
  const bool has_curves = !plot.curves.empty();
  const int curve_h = has_curves ? W / 4 : 0;
  const int below_axes = 60;  // tick labels and axis label under a panel
  const int H = title_h + legend_h + top_h + below_axes +
                (has_curves ? 30 + legend_h + curve_h + below_axes : 0);
  cv::Mat img(H, W, CV_8UC3, kWhite);

  // Title lines are separated by '\n'; the first is bold.
  int y = 28;
  size_t start = 0;
  for (int line = 0; line < title_lines; ++line) {
    const size_t nl = plot.title.find('\n', start);
    const std::string text_line =
        plot.title.substr(start, nl == std::string::npos ? nl : nl - start);
    text_centered(img, text_line, W / 2, y, line == 0 ? 0.7 : 0.5, line == 0 ? 2 : 1);
    y += 24;
    start = nl == std::string::npos ? plot.title.size() : nl + 1;
  }
  const cv::Rect top(left, title_h + legend_h, plot_w, top_h);
  draw_top_view(img, top, plot, view);
  if (has_curves) {
    const cv::Rect low(left, top.y + top_h + below_axes + 30 + legend_h, plot_w, curve_h);
    if (!plot.curve_title.empty()) {
      text_centered(img, plot.curve_title, W / 2, low.y - legend_h - 10, 0.6, 1);
    }
    draw_curves(img, low, plot);
  }
  return img;
}

void write_trajectory_plot(const TrajectoryPlot& plot, const std::string& path) {
  const cv::Mat img = render_trajectory_plot(plot);
  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot write plot '" + path + "': " + e.what());
  }
  if (!ok) throw std::runtime_error("cannot write plot '" + path + "'");
}

}  // namespace rdslam
