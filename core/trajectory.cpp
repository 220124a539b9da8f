#include "core/trajectory.h"

#include <Eigen/SVD>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string_view>

#include "core/timestamp.h"

namespace rdslam {
namespace {

[[noreturn]] void fail(const std::string& path, size_t line, const std::string& what) {
  throw std::runtime_error(path + ":" + std::to_string(line) + ": " + what);
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) {
    s.remove_prefix(1);
  }
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) {
    s.remove_suffix(1);
  }
  return s;
}

// Splits on whitespace and (when `commas`) on commas; empty fields between two commas are
// kept so "1,,2" is reported as malformed rather than silently shifted.
std::vector<std::string_view> split(std::string_view line, bool commas) {
  std::vector<std::string_view> out;
  if (commas) {
    size_t start = 0;
    while (true) {
      const size_t c = line.find(',', start);
      out.push_back(trim(line.substr(start, c == std::string_view::npos ? c : c - start)));
      if (c == std::string_view::npos) break;
      start = c + 1;
    }
    // A trailing comma ("...,0.03,") is common in hand-made CSVs: not a field.
    if (!out.empty() && out.back().empty()) out.pop_back();
    return out;
  }
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

double to_double(std::string_view tok, const std::string& path, size_t line, const char* what) {
  double v = 0.0;
  const char* begin = tok.data();
  const char* end = tok.data() + tok.size();
  if (!tok.empty() && *begin == '+') ++begin;  // from_chars rejects a leading '+'
  const auto r = std::from_chars(begin, end, v);
  if (tok.empty() || r.ec != std::errc() || r.ptr != end || !std::isfinite(v)) {
    fail(path, line, std::string(what) + ": '" + std::string(tok) + "' is not a finite number");
  }
  return v;
}

// Lines that carry no data: blank or comment ('#', also '%' as in some TUM tools).
bool is_skipped(std::string_view line) {
  const std::string_view t = trim(line);
  return t.empty() || t.front() == '#' || t.front() == '%';
}

Eigen::Quaterniond checked_quaternion(double w, double x, double y, double z,
                                      const std::string& path, size_t line) {
  Eigen::Quaterniond q(w, x, y, z);
  const double n = q.norm();
  // A unit quaternion written with 6 decimals has |q| within ~1e-5 of 1; anything far off is
  // a column mix-up (e.g. a position read as a quaternion), not rounding.
  if (!(std::fabs(n - 1.0) < 1e-2)) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "quaternion norm %.6g is not 1 (columns out of order?)", n);
    fail(path, line, buf);
  }
  q.coeffs() /= n;
  return q;
}

Trajectory read_tum(std::ifstream& in, const std::string& path) {
  Trajectory out;
  std::string text;
  for (size_t line = 1; std::getline(in, text); ++line) {
    if (is_skipped(text)) continue;
    const auto tok = split(text, /*commas=*/false);
    if (tok.size() != 8) {
      fail(path, line,
           "expected 8 values 't tx ty tz qx qy qz qw', found " + std::to_string(tok.size()));
    }
    StampedPose p;
    if (!parse_seconds_ns(tok[0], p.stamp_ns)) {
      fail(path, line, "timestamp '" + std::string(tok[0]) + "' is not a time in seconds");
    }
    for (int k = 0; k < 3; ++k) p.p_world_cam[k] = to_double(tok[1 + k], path, line, "position");
    const double qx = to_double(tok[4], path, line, "qx");
    const double qy = to_double(tok[5], path, line, "qy");
    const double qz = to_double(tok[6], path, line, "qz");
    const double qw = to_double(tok[7], path, line, "qw");
    p.q_world_cam = checked_quaternion(qw, qx, qy, qz, path, line);
    out.push_back(p);
  }
  return out;
}

// EuRoC/ASL state_groundtruth_estimate0/data.csv: "#timestamp [ns], p_RS_R_x [m], p_RS_R_y,
// p_RS_R_z, q_RS_w, q_RS_x, q_RS_y, q_RS_z, v..., b_w..., b_a...". Only the first 8 columns
// are used; a pose file with exactly 8 columns (EuRoC pose csv) is accepted as well.
Trajectory read_euroc(std::ifstream& in, const std::string& path) {
  Trajectory out;
  std::string text;
  for (size_t line = 1; std::getline(in, text); ++line) {
    if (is_skipped(text)) continue;
    const auto tok = split(text, /*commas=*/true);
    if (tok.size() < 8) {
      fail(
          path, line,
          "expected at least 8 comma-separated values 't[ns], px, py, pz, qw, qx, qy, qz', found " +
              std::to_string(tok.size()));
    }
    StampedPose p;
    const auto r = std::from_chars(tok[0].data(), tok[0].data() + tok[0].size(), p.stamp_ns);
    if (tok[0].empty() || r.ec != std::errc() || r.ptr != tok[0].data() + tok[0].size()) {
      fail(path, line, "timestamp '" + std::string(tok[0]) + "' is not an integer in ns");
    }
    for (int k = 0; k < 3; ++k) p.p_world_cam[k] = to_double(tok[1 + k], path, line, "position");
    const double qw = to_double(tok[4], path, line, "qw");
    const double qx = to_double(tok[5], path, line, "qx");
    const double qy = to_double(tok[6], path, line, "qy");
    const double qz = to_double(tok[7], path, line, "qz");
    for (size_t k = 8; k < tok.size(); ++k) to_double(tok[k], path, line, "column");
    p.q_world_cam = checked_quaternion(qw, qx, qy, qz, path, line);
    out.push_back(p);
  }
  return out;
}

// KITTI odometry poses: 12 numbers per line, the row-major 3x4 [R|t] of camera 0 at frame i
// in the camera-0 frame of frame 0, i.e. T_world_cam with world = first camera.
Trajectory read_kitti(std::ifstream& in, const std::string& path, int64_t period_ns) {
  Trajectory out;
  std::string text;
  int64_t index = 0;
  for (size_t line = 1; std::getline(in, text); ++line) {
    if (is_skipped(text)) continue;
    const auto tok = split(text, /*commas=*/false);
    if (tok.size() != 12) {
      fail(path, line,
           "expected 12 values (row-major 3x4 [R|t]), found " + std::to_string(tok.size()));
    }
    Eigen::Matrix3d R;
    StampedPose p;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) R(r, c) = to_double(tok[r * 4 + c], path, line, "rotation");
      p.p_world_cam[r] = to_double(tok[r * 4 + 3], path, line, "translation");
    }
    // KITTI writes R with ~7 significant digits: project onto SO(3) (closest rotation in
    // Frobenius norm) so the quaternion is exact for what the matrix means.
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d Rn = svd.matrixU() * svd.matrixV().transpose();
    if (Rn.determinant() < 0 || (Rn - R).norm() > 1e-2) {
      fail(path, line, "the 3x3 part is not a rotation matrix");
    }
    p.q_world_cam = Eigen::Quaterniond(Rn).normalized();
    p.stamp_ns = index * period_ns;
    ++index;
    out.push_back(p);
  }
  return out;
}

}  // namespace

Trajectory read_trajectory(const std::string& path, TrajectoryFormat format,
                           int64_t kitti_period_ns) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open trajectory file");
  switch (format) {
    case TrajectoryFormat::kTum:
      return read_tum(in, path);
    case TrajectoryFormat::kEuroc:
      return read_euroc(in, path);
    case TrajectoryFormat::kKitti:
      if (kitti_period_ns <= 0) {
        throw std::runtime_error(path + ": KITTI frame period must be positive");
      }
      return read_kitti(in, path, kitti_period_ns);
  }
  throw std::runtime_error(path + ": unknown trajectory format");
}

TrajectoryFormat detect_trajectory_format(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open trajectory file");
  std::string text;
  for (size_t line = 1; std::getline(in, text); ++line) {
    if (is_skipped(text)) continue;
    if (text.find(',') != std::string::npos) {
      const size_t n = split(text, true).size();
      if (n >= 8) return TrajectoryFormat::kEuroc;
      fail(path, line,
           "comma-separated line with " + std::to_string(n) +
               " values: not an EuRoC trajectory (needs >= 8)");
    }
    const size_t n = split(text, false).size();
    if (n == 8) return TrajectoryFormat::kTum;
    if (n == 12) return TrajectoryFormat::kKitti;
    fail(path, line,
         "cannot tell the trajectory format from a line with " + std::to_string(n) +
             " values (TUM has 8, KITTI 12, EuRoC is comma-separated)");
  }
  throw std::runtime_error(path + ": no data lines: cannot tell the trajectory format");
}

void write_trajectory_tum(const std::string& path, const Trajectory& traj) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  std::fprintf(f, "# timestamp tx ty tz qx qy qz qw\n");
  for (const auto& p : traj) {
    const Eigen::Quaterniond& q = p.q_world_cam;
    // %.17g: a double survives the text round trip exactly.
    std::fprintf(f, "%s %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                 format_seconds_ns(p.stamp_ns).c_str(), p.p_world_cam.x(), p.p_world_cam.y(),
                 p.p_world_cam.z(), q.x(), q.y(), q.z(), q.w());
  }
  const bool ok = std::ferror(f) == 0;
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error(path + ": write failed");
}

}  // namespace rdslam
