#include "firmware_app/debug_video.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/log.h"
#include "firmware_app/cli.h"

namespace rdslam {

namespace fs = std::filesystem;

namespace {

const int kFont = cv::FONT_HERSHEY_SIMPLEX;
const double kDim = 0.55;  // image brightness under the markers

cv::Scalar state_colour(TrackingState s) {
  switch (s) {
    case TrackingState::kTracking:
      return {0, 220, 0};
    case TrackingState::kRelocalized:
      return {255, 255, 0};
    case TrackingState::kLost:
      return {0, 0, 255};
    case TrackingState::kInitializing:
      break;
  }
  return {200, 200, 200};
}

void draw_cross(cv::Mat& img, cv::Point2f c, int r, const cv::Scalar& colour, int thickness = 1) {
  const cv::Point p(cvRound(c.x), cvRound(c.y));
  cv::line(img, p + cv::Point(-r, -r), p + cv::Point(r, r), colour, thickness, cv::LINE_8);
  cv::line(img, p + cv::Point(-r, r), p + cv::Point(r, -r), colour, thickness, cv::LINE_8);
}

// Text with a dark outline so it stays legible on any background.
void put_text(cv::Mat& img, const std::string& s, cv::Point org, double scale,
              const cv::Scalar& colour) {
  cv::putText(img, s, org, kFont, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(img, s, org, kFont, scale, colour, 1, cv::LINE_AA);
}

// Writes `text` at `x` and returns the x after it.
int put_run(cv::Mat& img, const std::string& s, int x, int y, double scale,
            const cv::Scalar& colour) {
  put_text(img, s, {x, y}, scale, colour);
  int base = 0;
  return x + cv::getTextSize(s, kFont, scale, 1, &base).width;
}

int even(int v) {
  return v + (v & 1);
}

}  // namespace

DebugRenderer::DebugRenderer(const CameraModel& camera, int recent_frames)
    : camera_(camera), recent_frames_(std::max(1, recent_frames)) {
  panel_ = camera_.height;
  canvas_ = cv::Size(even(camera_.width + panel_), even(header_h_ + camera_.height));
}

int64_t DebugRenderer::frame_number(const DebugFrame& d) const {
  return d.dataset_index >= 0 ? d.dataset_index : observed_ - 1;
}

bool DebugRenderer::recent(int64_t id) const {
  auto it = first_seen_.find(id);
  return it != first_seen_.end() && observed_ - 1 - it->second < recent_frames_;
}

void DebugRenderer::observe(const DebugFrame& d) {
  const int64_t n = observed_++;
  if (d.result.state == TrackingState::kTracking || d.result.state == TrackingState::kRelocalized) {
    track_.push_back(d.T_cam_world.centre());
  }
  recent_count_ = 0;
  if (!d.snapshot) return;
  const MapSnapshot& s = *d.snapshot;
  if (s.epoch != epoch_) {  // a new map: ids start again
    first_seen_.clear();
    track_.clear();
    have_bounds_ = false;
    epoch_ = s.epoch;
  }
  for (int64_t id : s.invalid_ids) first_seen_.emplace(id, n);
  if (first_seen_.size() > 2 * s.invalid_ids.size() + 4096) {
    // Forget ids the snapshot no longer lists (it keeps the newest ones).
    std::unordered_map<int64_t, int64_t> keep;
    for (int64_t id : s.invalid_ids) keep.emplace(id, first_seen_[id]);
    first_seen_.swap(keep);
  }
  for (int64_t id : s.invalid_ids) recent_count_ += recent(id);
  update_bounds(d);
}

void DebugRenderer::update_bounds(const DebugFrame& d) {
  // Expand-only bounds of the top view: keyframe centres, the track, and the 5-95% range of
  // the map points (robust to a few far outliers), so the view does not jump from frame to
  // frame.
  xs_.clear();
  zs_.clear();
  const MapSnapshot& s = *d.snapshot;
  for (const auto& p : s.p_world) {
    xs_.push_back(p.x());
    zs_.push_back(p.z());
  }
  auto extend = [this](double x, double z) {
    if (!have_bounds_) {
      min_x_ = max_x_ = x;
      min_z_ = max_z_ = z;
      have_bounds_ = true;
    }
    min_x_ = std::min(min_x_, x);
    max_x_ = std::max(max_x_, x);
    min_z_ = std::min(min_z_, z);
    max_z_ = std::max(max_z_, z);
  };
  if (xs_.size() >= 20) {
    auto pct = [](std::vector<double>& v, double q) {
      const size_t k = static_cast<size_t>(q * double(v.size() - 1));
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
      return v[k];
    };
    extend(pct(xs_, 0.05), pct(zs_, 0.05));
    extend(pct(xs_, 0.95), pct(zs_, 0.95));
  }
  for (const Pose& T : s.kf_pose) {
    const Eigen::Vector3d c = T.centre();
    extend(c.x(), c.z());
  }
  if (!track_.empty()) extend(track_.back().x(), track_.back().z());
}

void DebugRenderer::project(
    const Pose& T, const std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>& p,
    std::vector<cv::Point2f>& uv, std::vector<uint8_t>& ok) const {
  // Map points are in ideal (undistorted) coordinates; the image is raw: distort with the
  // camera model so the dots land on the features.
  uv.assign(p.size(), cv::Point2f(-1, -1));
  ok.assign(p.size(), 0);
  std::vector<cv::Point3d> pc;
  std::vector<size_t> idx;
  pc.reserve(p.size());
  idx.reserve(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector3d c = T * p[i];
    if (c.z() <= 1e-6) continue;
    pc.emplace_back(c.x(), c.y(), c.z());
    idx.push_back(i);
  }
  if (pc.empty()) return;
  std::vector<cv::Point2d> out;
  const cv::Vec3d zero(0, 0, 0);
  if (!camera_.has_distortion()) {
    out.resize(pc.size());
    for (size_t k = 0; k < pc.size(); ++k) {
      out[k] = {camera_.fx * pc[k].x / pc[k].z + camera_.cx,
                camera_.fy * pc[k].y / pc[k].z + camera_.cy};
    }
  } else if (camera_.is_equidistant()) {
    cv::fisheye::projectPoints(pc, out, zero, zero, camera_.K(), camera_.dist_coeffs());
  } else {
    cv::projectPoints(pc, zero, zero, camera_.K(), camera_.dist_coeffs(), out);
  }
  for (size_t k = 0; k < out.size(); ++k) {
    const cv::Point2d& q = out[k];
    if (q.x < 0 || q.y < 0 || q.x >= camera_.width || q.y >= camera_.height) continue;
    uv[idx[k]] = cv::Point2f(float(q.x), float(q.y));
    ok[idx[k]] = 1;
  }
}

void DebugRenderer::render(const DebugFrame& d, cv::Mat& canvas) {
  canvas.create(canvas_, CV_8UC3);
  canvas.setTo(cv::Scalar(24, 24, 24));
  const int W = camera_.width, H = camera_.height;

  // Camera image, dimmed so the markers stand out.
  cv::Mat view = canvas(cv::Rect(0, header_h_, W, H));
  if (d.image.empty()) {
    view.setTo(cv::Scalar(0, 0, 0));
  } else {
    const cv::Mat* src = &d.image;
    if (d.image.channels() == 1) {
      cv::cvtColor(d.image, bgr_, cv::COLOR_GRAY2BGR);
      src = &bgr_;
    }
    if (src->size() == view.size()) {
      src->convertTo(view, CV_8UC3, kDim);
    } else {
      cv::Mat tmp;
      cv::resize(*src, tmp, view.size());
      tmp.convertTo(view, CV_8UC3, kDim);
    }
  }

  int invalid_drawn = 0;
  if (d.has_pose && d.snapshot) {
    const MapSnapshot& s = *d.snapshot;
    project(d.T_cam_world, s.p_world, uv_, ok_);
    for (size_t i = 0; i < uv_.size(); ++i) {
      if (ok_[i]) cv::circle(view, uv_[i], 2, DebugColours::map_point(), cv::FILLED, cv::LINE_8);
    }
    project(d.T_cam_world, s.invalid_p_world, uv_, ok_);
    for (size_t i = 0; i < uv_.size(); ++i) {
      if (!ok_[i] || !recent(s.invalid_ids[i])) continue;
      cv::circle(view, uv_[i], 3, DebugColours::invalidated(), cv::FILLED, cv::LINE_8);
      ++invalid_drawn;
    }
  }
  for (const DebugFeature& f : d.features) {
    const cv::Point2f p(f.x, f.y);
    switch (f.kind) {
      case DebugFeatureKind::kRejectedRobust:
        draw_cross(view, p, 4, DebugColours::rejected_robust(), 2);
        break;
      case DebugFeatureKind::kRejectedRefine:
        draw_cross(view, p, 3, DebugColours::rejected_refine());
        break;
      case DebugFeatureKind::kUnsupported:
        cv::circle(view, p, 3, DebugColours::unsupported(), 1, cv::LINE_8);
        break;
      case DebugFeatureKind::kInlier:
      case DebugFeatureKind::kUnmatched:
        break;
    }
  }
  for (const DebugFeature& f : d.features) {  // inliers on top
    if (f.kind != DebugFeatureKind::kInlier) continue;
    cv::circle(view, cv::Point2f(f.x, f.y), 2, DebugColours::inlier(), cv::FILLED, cv::LINE_8);
  }

  // Header: two lines of facts.
  const double fs = 0.5;
  const TrackResult& r = d.result;
  char buf[256];
  std::snprintf(buf, sizeof(buf), "frame %lld", static_cast<long long>(frame_number(d)));
  int x = put_run(canvas, buf, 8, 19, fs, cv::Scalar(255, 255, 255));
  x = put_run(canvas, std::string("  ") + to_string(r.state), x, 19, fs, state_colour(r.state));
  std::snprintf(buf, sizeof(buf), "   inliers %d", count_features(d, DebugFeatureKind::kInlier));
  x = put_run(canvas, buf, x, 19, fs, DebugColours::inlier());
  std::snprintf(buf, sizeof(buf), "   rejected: robust %d",
                count_features(d, DebugFeatureKind::kRejectedRobust));
  x = put_run(canvas, buf, x, 19, fs, DebugColours::rejected_robust());
  std::snprintf(buf, sizeof(buf), "  eq.(1) %d",
                count_features(d, DebugFeatureKind::kRejectedRefine));
  x = put_run(canvas, buf, x, 19, fs, DebugColours::rejected_refine());
  const int unsupported = count_features(d, DebugFeatureKind::kUnsupported);
  if (unsupported > 0) {
    std::snprintf(buf, sizeof(buf), "  unsupported %d", unsupported);
    put_run(canvas, buf, x, 19, fs, DebugColours::unsupported());
  }
  std::snprintf(buf, sizeof(buf), "map %d points, %d keyframes", r.map_points, r.keyframes);
  x = put_run(canvas, buf, 8, 40, fs, DebugColours::map_point());
  std::snprintf(buf, sizeof(buf), "   invalidated %lld so far", (long long)r.invalidated_points);
  x = put_run(canvas, buf, x, 40, fs, DebugColours::invalidated());
  std::snprintf(buf, sizeof(buf), " (red: %d in view, last %d frames)", invalid_drawn,
                recent_frames_);
  put_run(canvas, buf, x, 40, fs, cv::Scalar(200, 200, 200));

  draw_panel(d, canvas(panel_rect()));
}

void DebugRenderer::draw_panel(const DebugFrame& d, cv::Mat panel) {
  panel.setTo(cv::Scalar(40, 40, 40));
  const int P = panel.cols;
  const int legend_h = 44;
  const int margin = 12;
  const int plot_h = std::max(16, P - legend_h - 2 * margin);
  const int plot_w = P - 2 * margin;
  if (have_bounds_) {
    const double ex = std::max(1e-3, max_x_ - min_x_), ez = std::max(1e-3, max_z_ - min_z_);
    const double scale = 0.94 * std::min(plot_w / ex, plot_h / ez);
    const double cx = 0.5 * (min_x_ + max_x_), cz = 0.5 * (min_z_ + max_z_);
    auto to_px = [&](const Eigen::Vector3d& p) {
      return cv::Point2f(float(margin + 0.5 * plot_w + (p.x() - cx) * scale),
                         float(margin + 0.5 * plot_h - (p.z() - cz) * scale));
    };
    const cv::Rect plot(0, 0, P, margin + plot_h + margin / 2);
    auto inside = [&](const cv::Point2f& q) { return plot.contains(cv::Point(q)); };
    if (d.snapshot) {
      const MapSnapshot& s = *d.snapshot;
      for (const auto& p : s.p_world) {
        const cv::Point2f q = to_px(p);
        if (inside(q)) panel.at<cv::Vec3b>(cv::Point(q)) = cv::Vec3b(255, 255, 0);
      }
      for (size_t i = 0; i < s.invalid_p_world.size(); ++i) {
        const cv::Point2f q = to_px(s.invalid_p_world[i]);
        if (!inside(q)) continue;
        if (recent(s.invalid_ids[i])) {
          cv::circle(panel, q, 2, DebugColours::invalidated(), cv::FILLED, cv::LINE_8);
        } else {
          panel.at<cv::Vec3b>(cv::Point(q)) = cv::Vec3b(0, 0, 150);  // older: dark red
        }
      }
      for (const Pose& T : s.kf_pose) {
        const cv::Point2f q = to_px(T.centre());
        if (inside(q)) {
          cv::rectangle(panel, cv::Rect(cvRound(q.x) - 2, cvRound(q.y) - 2, 5, 5),
                        DebugColours::keyframe(), 1);
        }
      }
    }
    for (size_t i = 1; i < track_.size(); ++i) {
      cv::line(panel, to_px(track_[i - 1]), to_px(track_[i]), DebugColours::track(), 1,
               cv::LINE_AA);
    }
    if (d.has_pose) {
      const Eigen::Vector3d c = d.T_cam_world.centre();
      const Eigen::Vector3d axis = d.T_cam_world.R.transpose().col(2);  // optical axis, world
      const cv::Point2f q = to_px(c);
      const double len = 0.06 * std::max(ex, ez);
      cv::line(panel, q, to_px(c + axis * len), state_colour(d.result.state), 2, cv::LINE_AA);
      cv::circle(panel, q, 4, state_colour(d.result.state), 2, cv::LINE_AA);
    }
  }
  put_text(panel, "top view (x right, z up)", {8, 16}, 0.4, cv::Scalar(200, 200, 200));
  // Legend, two rows.
  const double ls = 0.4;
  const int y1 = P - legend_h + 16, y2 = P - legend_h + 36;
  int x = 8;
  cv::circle(panel, {x + 3, y1 - 4}, 3, DebugColours::inlier(), cv::FILLED);
  x = put_run(panel, "inlier", x + 10, y1, ls, DebugColours::inlier()) + 10;
  draw_cross(panel, cv::Point2f(float(x + 3), float(y1 - 4)), 4, DebugColours::rejected_robust(),
             2);
  x = put_run(panel, "robust out", x + 10, y1, ls, DebugColours::rejected_robust()) + 10;
  draw_cross(panel, cv::Point2f(float(x + 3), float(y1 - 4)), 3, DebugColours::rejected_refine());
  put_run(panel, "eq.(1) out", x + 10, y1, ls, DebugColours::rejected_refine());
  x = 8;
  cv::circle(panel, {x + 3, y2 - 4}, 2, DebugColours::map_point(), cv::FILLED);
  x = put_run(panel, "map point", x + 10, y2, ls, DebugColours::map_point()) + 10;
  cv::circle(panel, {x + 3, y2 - 4}, 3, DebugColours::invalidated(), cv::FILLED);
  x = put_run(panel, "invalidated", x + 10, y2, ls, DebugColours::invalidated()) + 10;
  cv::rectangle(panel, cv::Rect(x + 1, y2 - 6, 5, 5), DebugColours::keyframe(), 1);
  x = put_run(panel, "keyframe", x + 10, y2, ls, DebugColours::keyframe()) + 10;
  cv::line(panel, {x, y2 - 4}, {x + 8, y2 - 4}, DebugColours::track(), 1);
  put_run(panel, "track", x + 11, y2, ls, DebugColours::track());
}

// ---------------------------------------------------------------------------------------

void check_debug_output_paths(const DebugVideoOptions& o) {
  if (o.every < 1) throw UsageError("--debug-every: must be an integer >= 1");
  if (!o.video_path.empty()) {
    const fs::path p(o.video_path);
    const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) {
      throw UsageError("--debug-video: cannot write '" + o.video_path + "': directory '" +
                       dir.string() + "' does not exist");
    }
    if (fs::is_directory(p, ec)) {
      throw UsageError("--debug-video: cannot write '" + o.video_path + "': is a directory");
    }
  }
  if (!o.images_dir.empty()) {
    const fs::path dir(o.images_dir);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (!fs::is_directory(dir)) {
      throw UsageError("--debug-images: cannot create directory '" + o.images_dir + "'" +
                       (ec ? ": " + ec.message() : std::string()));
    }
    // A real write, not access(): root passes access() checks on read-only mounts.
    const std::string probe = (dir / ".rdslam_write_probe").string();
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) {
      throw UsageError("--debug-images: cannot write into '" + o.images_dir + "'");
    }
    ::close(fd);
    ::unlink(probe.c_str());
  }
}

DebugVideoWriter::DebugVideoWriter(const DebugVideoOptions& options, const CameraModel& camera)
    : options_(options), renderer_(camera, options.recent_frames) {
  check_debug_output_paths(options_);
  if (!options_.video_path.empty()) {
    // H.264 ('avc1') when this OpenCV's FFmpeg has an encoder for it, else MPEG-4 Part 2.
    // OpenCV logs its own errors for a codec it lacks: silence them while probing.
    const auto level = cv::utils::logging::getLogLevel();
    cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
    for (const char* cc : {"avc1", "mp4v"}) {
      const double fps = options_.fps > 0 ? options_.fps : 30.0;
      if (video_.open(options_.video_path, cv::CAP_FFMPEG,
                      cv::VideoWriter::fourcc(cc[0], cc[1], cc[2], cc[3]), fps,
                      renderer_.canvas_size())) {
        stats_.codec = cc;
        break;
      }
    }
    cv::utils::logging::setLogLevel(level);
    if (!video_.isOpened()) {
      throw UsageError("--debug-video: cannot open '" + options_.video_path +
                       "' for writing (no avc1 or mp4v encoder in OpenCV's FFmpeg for this "
                       "file type, or the file cannot be created)");
    }
  }
  thread_ = std::thread([this] { worker(); });
}

DebugVideoWriter::~DebugVideoWriter() {
  finish();
}

void DebugVideoWriter::on_debug_frame(DebugFrame&& frame) {
  auto rec = std::make_unique<DebugFrame>(std::move(frame));
  std::unique_lock<std::mutex> lock(mutex_);
  ++stats_.received;
  const size_t cap = static_cast<size_t>(std::max(1, options_.queue_frames));
  if (queue_.size() >= cap) {
    if (!options_.lossless) {
      ++stats_.dropped;
      return;
    }
    not_full_.wait(lock, [&] { return queue_.size() < cap || closing_; });
    if (closing_) return;
  }
  queue_.push_back(std::move(rec));
  not_empty_.notify_one();
}

void DebugVideoWriter::worker() {
  for (;;) {
    std::unique_ptr<DebugFrame> d;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      not_empty_.wait(lock, [&] { return !queue_.empty() || closing_; });
      if (queue_.empty()) return;  // closing and drained
      d = std::move(queue_.front());
      queue_.pop_front();
      not_full_.notify_one();
    }
    try {
      write(*d);
    } catch (const std::exception& e) {  // e.g. cv::Exception: keep the replay running
      if (stats_.error.empty()) stats_.error = std::string("drawing failed: ") + e.what();
      RDSLAM_LOG_ERROR("debug video: %s", e.what());
    }
  }
}

void DebugVideoWriter::write(const DebugFrame& d) {
  renderer_.observe(d);
  // Every N-th record is drawn, counted in arrival order (dataset indices may have gaps);
  // the PNG is named by the header's frame number.
  if ((observed_++ % options_.every) != 0) return;
  const int64_t index = renderer_.frame_number(d);
  renderer_.render(d, canvas_);
  ++stats_.drawn;
  if (video_.isOpened()) {
    video_.write(canvas_);
    ++stats_.video_frames;
  }
  if (!options_.images_dir.empty()) {
    char name[64];
    std::snprintf(name, sizeof(name), "frame_%06lld.png", static_cast<long long>(index));
    const std::string path = (fs::path(options_.images_dir) / name).string();
    bool ok = false;
    try {
      ok = cv::imwrite(path, canvas_);
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (ok) {
      ++stats_.images;
    } else if (stats_.error.empty()) {
      stats_.error = "cannot write " + path;
      RDSLAM_LOG_ERROR("debug video: %s", stats_.error.c_str());
    }
  }
}

DebugVideoStats DebugVideoWriter::finish() {
  if (finished_) return stats_;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closing_ = true;
  }
  not_empty_.notify_all();
  not_full_.notify_all();
  if (thread_.joinable()) thread_.join();
  video_.release();
  finished_ = true;
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace rdslam
