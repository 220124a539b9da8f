#include "drivers/dataset_kitti.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace rdslam {

namespace fs = std::filesystem;

std::string kitti_image_dir(const std::string& dir) {
  for (const char* sub : {"image_0", "image_l"}) {
    const fs::path p = fs::path(dir) / sub;
    if (fs::is_directory(p)) return p.string();
  }
  return {};
}

bool looks_like_kitti(const std::string& dir) {
  return !kitti_image_dir(dir).empty();
}

CameraModel read_kitti_calib(const std::string& path, int width, int height) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open KITTI calib.txt");
  std::string line;
  std::vector<double> p;
  size_t n = 0;
  bool found = false;
  while (!found && std::getline(in, line)) {
    ++n;
    std::istringstream ss(line);
    std::string first;
    if (!(ss >> first)) continue;
    if (first.back() == ':') {
      if (first != "P0:") continue;  // official layout: "P0: ...", "P1: ...", "Tr: ..."
    } else {
      ss.clear();
      ss.str(line);  // bare numbers: the first data line is P0
    }
    std::string tok;
    while (ss >> tok) {
      double v = 0;
      const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
      if (r.ec != std::errc() || r.ptr != tok.data() + tok.size() || !std::isfinite(v)) {
        throw std::runtime_error(path + ":" + std::to_string(n) + ": '" + tok +
                                 "' is not a number");
      }
      p.push_back(v);
    }
    found = true;
  }
  if (!found) throw std::runtime_error(path + ": no P0 line");
  if (p.size() != 12) {
    throw std::runtime_error(path + ":" + std::to_string(n) + ": P0 needs 12 numbers, found " +
                             std::to_string(p.size()));
  }
  CameraModel cam;
  cam.model = "pinhole-radtan";
  cam.width = width;
  cam.height = height;
  cam.fx = p[0];
  cam.fy = p[5];
  cam.cx = p[2];
  cam.cy = p[6];
  cam.k1 = cam.k2 = cam.p1 = cam.p2 = cam.k3 = cam.k4 = 0.0;  // rectified images
  if (!(cam.fx > 0 && cam.fy > 0))
    throw std::runtime_error(path + ": P0 has no positive focal length");
  const std::string err = cam.validate();
  if (!err.empty()) throw std::runtime_error(path + ": " + err);
  return cam;
}

std::vector<int64_t> read_kitti_times(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::vector<int64_t> out;
  std::string line;
  for (size_t n = 1; std::getline(in, line); ++n) {
    std::istringstream ss(line);
    std::string tok, extra;
    if (!(ss >> tok)) continue;
    double s = 0;
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), s);
    if (r.ec != std::errc() || r.ptr != tok.data() + tok.size() || !std::isfinite(s) ||
        (ss >> extra)) {
      throw std::runtime_error(path + ":" + std::to_string(n) + ": expected one time in seconds");
    }
    // KITTI times are relative (< 1e4 s): double resolves them to well below 1 ns.
    out.push_back(std::llround(s * 1e9));
  }
  return out;
}

std::unique_ptr<ReplaySource> open_kitti_source(const std::string& uri, const std::string& dir,
                                                double rate_hz, double speed) {
  const std::string image_dir = kitti_image_dir(dir);
  if (image_dir.empty()) {
    throw std::runtime_error(dir + ": not a KITTI odometry sequence (no image_0/ or image_l/)");
  }
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(image_dir)) {
    if (e.is_regular_file() && has_image_extension(e.path().filename().string())) {
      names.push_back(e.path().filename().string());
    }
  }
  std::sort(names.begin(), names.end(), natural_less);
  if (names.empty()) throw std::runtime_error(image_dir + ": no images");

  const fs::path times_path = fs::path(dir) / "times.txt";
  std::vector<int64_t> times;
  int64_t period_ns = 0;
  if (fs::is_regular_file(times_path)) {
    times = read_kitti_times(times_path.string());
    if (times.size() != names.size()) {
      throw std::runtime_error(times_path.string() + ": has " + std::to_string(times.size()) +
                               " times for " + std::to_string(names.size()) + " images");
    }
  } else {
    if (!(rate_hz > 0.0)) throw std::runtime_error(uri + ": KITTI frame rate must be positive");
    period_ns = std::llround(1e9 / rate_hz);
  }
  std::vector<ImageFileSequence::Item> items;
  items.reserve(names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    items.push_back({times.empty() ? static_cast<int64_t>(i) * period_ns : times[i],
                     (fs::path(image_dir) / names[i]).string()});
  }

  int width = 0, height = 0;
  PixelFormat format = PixelFormat::kGray8;
  probe_image(items.front().path, width, height, format);
  std::optional<CameraModel> camera;
  const fs::path calib = fs::path(dir) / "calib.txt";
  if (fs::is_regular_file(calib)) camera = read_kitti_calib(calib.string(), width, height);

  std::optional<Trajectory> gt;
  fs::path abs = fs::absolute(fs::path(dir)).lexically_normal();
  if (!abs.has_filename()) abs = abs.parent_path();  // "dir/" -> "dir"
  const std::string seq_name = abs.filename().string();
  for (const fs::path& poses : {fs::path(dir) / "poses.txt",
                                abs.parent_path().parent_path() / "poses" / (seq_name + ".txt")}) {
    if (!fs::is_regular_file(poses)) continue;
    Trajectory t = read_trajectory(poses.string(), TrajectoryFormat::kKitti,
                                   period_ns > 0 ? period_ns : 100000000);
    // Pose i belongs to image i: give it that image's time. Poses past the last image (an
    // excerpt of a longer sequence) describe frames that are not here.
    if (t.size() > items.size()) t.resize(items.size());
    for (size_t i = 0; i < t.size(); ++i) t[i].stamp_ns = items[i].stamp_ns;
    gt = std::move(t);
    break;
  }
  return make_image_replay(uri, "kitti", std::move(items), camera, std::move(gt), speed);
}

}  // namespace rdslam
