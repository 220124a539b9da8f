#include "drivers/replay_source.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace rdslam {

namespace {

class SystemMonoClock : public MonoClock {
 public:
  int64_t now_ns() override { return mono_now_ns(); }
  void sleep_until_ns(int64_t deadline_ns) override {
    if (deadline_ns <= 0) return;
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(deadline_ns / 1000000000LL);
    ts.tv_nsec = static_cast<long>(deadline_ns % 1000000000LL);
    // Absolute deadline: a signal (EINTR) just resumes the same sleep, and a late wake-up
    // never shifts the following deadlines.
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
};

}  // namespace

MonoClock& system_mono_clock() {
  static SystemMonoClock clock;
  return clock;
}

ReplaySource::ReplaySource(std::unique_ptr<RecordedSequence> sequence, SourceInfo info,
                           std::optional<CameraModel> camera,
                           std::optional<Trajectory> ground_truth, double speed, MonoClock& clock)
    : seq_(std::move(sequence)),
      info_(std::move(info)),
      camera_(std::move(camera)),
      ground_truth_(std::move(ground_truth)),
      speed_(speed > 0.0 && std::isfinite(speed) ? speed : 0.0),
      clock_(clock) {
  // Paced replay behaves like a camera: frames arrive in real time whether or not anyone
  // reads, so the pipeline must apply its live (drop) policy.
  info_.live = speed_ > 0.0;
  if (speed_ > 0.0) {
    staging_.create(info_.height, info_.width,
                    info_.format == PixelFormat::kGray8 ? CV_8UC1 : CV_8UC3);
  }
}

SourceStatus ReplaySource::read(Frame& out, int timeout_ms) {
  if (eos_) return SourceStatus::kEndOfStream;
  return speed_ > 0.0 ? read_paced(out, timeout_ms) : read_unpaced(out);
}

void ReplaySource::fill(Frame& out, int64_t index, int64_t stamp_ns, int64_t arrival_ns) {
  out.format = info_.format;
  out.stamp_ns = stamp_ns;
  out.arrival_mono_ns = arrival_ns;
  // Recorded frames are numbered by their index: a gap in seq shows skipped frames, as the
  // V4L2 sequence number does for a live camera.
  out.seq = static_cast<uint64_t>(index);
  out.dataset_index = index;
  ++counters_.delivered;
}

SourceStatus ReplaySource::read_unpaced(Frame& out) {
  int64_t stamp_ns = 0;
  if (!seq_->stamp(next_, stamp_ns)) {
    eos_ = true;
    return SourceStatus::kEndOfStream;
  }
  const int64_t index = next_;
  const SourceStatus st = seq_->load(index, out.image);
  if (st == SourceStatus::kEndOfStream) {
    eos_ = true;
    return st;
  }
  ++next_;
  if (st != SourceStatus::kOk) {
    ++counters_.faults;
    return SourceStatus::kFault;
  }
  fill(out, index, stamp_ns, clock_.now_ns());
  return SourceStatus::kOk;
}

int64_t ReplaySource::due_ns(int64_t stamp_ns) const {
  return t0_ns_ + std::llround(static_cast<double>(stamp_ns - stamp0_ns_) / speed_);
}

SourceStatus ReplaySource::read_paced(Frame& out, int timeout_ms) {
  const int64_t call_ns = clock_.now_ns();
  if (!staged_) {
    // The newest due frame wins: pass over every frame whose successor is already due.
    // Skipped frames are not decoded (a video sequence has to grab them, nothing more).
    int64_t next_stamp = 0;
    while (started_ && seq_->stamp(next_ + 1, next_stamp) && due_ns(next_stamp) <= call_ns) {
      ++next_;
      ++counters_.skipped;
    }
    if (!seq_->stamp(next_, staged_stamp_ns_)) {
      eos_ = true;
      return SourceStatus::kEndOfStream;
    }
    // Decode ahead of the deadline so decoding does not delay delivery.
    const SourceStatus st = seq_->load(next_, staging_);
    if (st == SourceStatus::kEndOfStream) {
      eos_ = true;
      return st;
    }
    if (st != SourceStatus::kOk) {
      ++next_;
      ++counters_.faults;
      return SourceStatus::kFault;
    }
    staged_ = true;
    if (!started_) {
      // The schedule starts when the first frame is ready, so it is due at once and its
      // decoding time does not count as lateness.
      started_ = true;
      t0_ns_ = clock_.now_ns();
      stamp0_ns_ = staged_stamp_ns_;
    }
  }
  const int64_t due = due_ns(staged_stamp_ns_);
  if (due > clock_.now_ns()) {
    const int64_t limit = call_ns + static_cast<int64_t>(std::max(timeout_ms, 0)) * 1000000LL;
    if (due > limit) {
      // Not due within the timeout: the frame stays staged for the next call.
      clock_.sleep_until_ns(limit);
      ++counters_.timeouts;
      return SourceStatus::kTimeout;
    }
    clock_.sleep_until_ns(due);
  }
  staging_.copyTo(out.image);  // no allocation once out.image has this size and type
  fill(out, next_, staged_stamp_ns_, due);
  staged_ = false;
  ++next_;
  return SourceStatus::kOk;
}

// ---------------------------------------------------------------------------------------

SourceStatus ImageFileDecoder::decode(const std::string& path, PixelFormat format, int width,
                                      int height, cv::Mat& out) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return SourceStatus::kFault;
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size <= 0) {
    ::close(fd);
    return SourceStatus::kFault;
  }
  bytes_.resize(static_cast<size_t>(st.st_size));  // keeps capacity: grows only for larger files
  size_t got = 0;
  while (got < bytes_.size()) {
    const ssize_t n = ::read(fd, bytes_.data() + got, bytes_.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  if (got != bytes_.size()) return SourceStatus::kFault;
  try {
    cv::imdecode(cv::_InputArray(bytes_.data(), static_cast<int>(bytes_.size())),
                 cv::IMREAD_UNCHANGED, &scratch_);
  } catch (const cv::Exception&) {
    return SourceStatus::kFault;
  }
  if (scratch_.empty() || scratch_.depth() != CV_8U) return SourceStatus::kFault;
  if (width > 0 && height > 0 && (scratch_.cols != width || scratch_.rows != height)) {
    return SourceStatus::kFault;
  }
  const int ch = scratch_.channels();
  if (format == PixelFormat::kGray8) {
    if (ch == 1) {
      scratch_.copyTo(out);
    } else if (ch == 3) {
      cv::cvtColor(scratch_, out, cv::COLOR_BGR2GRAY);
    } else if (ch == 4) {
      cv::cvtColor(scratch_, out, cv::COLOR_BGRA2GRAY);
    } else {
      return SourceStatus::kFault;
    }
  } else {
    if (ch == 1) {
      cv::cvtColor(scratch_, out, cv::COLOR_GRAY2BGR);
    } else if (ch == 3) {
      scratch_.copyTo(out);
    } else if (ch == 4) {
      cv::cvtColor(scratch_, out, cv::COLOR_BGRA2BGR);
    } else {
      return SourceStatus::kFault;
    }
  }
  return SourceStatus::kOk;
}

void probe_image(const std::string& path, int& width, int& height, PixelFormat& format) {
  const cv::Mat img = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (img.empty()) throw std::runtime_error(path + ": not a readable image");
  if (img.depth() != CV_8U) {
    throw std::runtime_error(path + ": only 8-bit images are supported (this one has " +
                             std::to_string(img.elemSize1() * 8) + " bits per channel)");
  }
  width = img.cols;
  height = img.rows;
  format = img.channels() == 1 ? PixelFormat::kGray8 : PixelFormat::kBgr8;
}

bool ImageFileSequence::stamp(int64_t index, int64_t& stamp_ns) const {
  if (index < 0 || index >= static_cast<int64_t>(items_.size())) return false;
  stamp_ns = items_[static_cast<size_t>(index)].stamp_ns;
  return true;
}

SourceStatus ImageFileSequence::load(int64_t index, cv::Mat& image) {
  if (index < 0 || index >= static_cast<int64_t>(items_.size())) {
    return SourceStatus::kEndOfStream;
  }
  // Read-ahead before decoding: the kernel fetches the coming files while we decode.
  const int64_t last =
      std::min<int64_t>(index + kReadAhead, static_cast<int64_t>(items_.size()) - 1);
  for (int64_t j = std::max(advised_ + 1, index + 1); j <= last; ++j) {
    const int fd = ::open(items_[static_cast<size_t>(j)].path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) continue;  // reported when the frame itself is loaded
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_WILLNEED);
    ::close(fd);
  }
  advised_ = std::max(advised_, last);
  return decoder_.decode(items_[static_cast<size_t>(index)].path, format_, width_, height_, image);
}

std::unique_ptr<ReplaySource> make_image_replay(const std::string& uri, const std::string& kind,
                                                std::vector<ImageFileSequence::Item> items,
                                                std::optional<CameraModel> camera,
                                                std::optional<Trajectory> ground_truth,
                                                double speed) {
  if (items.empty()) throw std::runtime_error(uri + ": the sequence has no frames");
  SourceInfo info;
  info.uri = uri;
  info.kind = kind;
  probe_image(items.front().path, info.width, info.height, info.format);
  info.frame_count = static_cast<int64_t>(items.size());
  if (items.size() >= 2) {
    std::vector<int64_t> steps;
    steps.reserve(items.size() - 1);
    for (size_t i = 1; i < items.size(); ++i) {
      steps.push_back(items[i].stamp_ns - items[i - 1].stamp_ns);
    }
    std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
    const int64_t median = steps[steps.size() / 2];
    if (median > 0) info.nominal_fps = 1e9 / static_cast<double>(median);
  }
  auto seq =
      std::make_unique<ImageFileSequence>(std::move(items), info.format, info.width, info.height);
  return std::make_unique<ReplaySource>(std::move(seq), std::move(info), std::move(camera),
                                        std::move(ground_truth), speed);
}

// ---------------------------------------------------------------------------------------

namespace {

// Reads CameraModel fields from one YAML mapping; records the keys it knows.
class YamlCameraReader : public ParamVisitor {
 public:
  YamlCameraReader(const YAML::Node& node, const std::string& path) : node_(node), path_(path) {}
  void field(const char* key, int& value, int lo, int hi, const char*) override {
    known_.push_back(key);
    const YAML::Node n = node_[key];
    if (!n) return;
    double v = 0;
    if (!as_number(n, v) || v != std::floor(v) || v < lo || v > hi) {
      bad(key, n, "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    value = static_cast<int>(v);
  }
  void field(const char* key, double& value, double lo, double hi, const char*) override {
    known_.push_back(key);
    const YAML::Node n = node_[key];
    if (!n) return;
    double v = 0;
    if (!as_number(n, v) || v < lo || v > hi) {
      char buf[96];
      std::snprintf(buf, sizeof(buf), "a number in [%g, %g]", lo, hi);
      bad(key, n, buf);
    }
    value = v;
  }
  void field(const char* key, bool&, const char*) override { known_.push_back(key); }
  void field(const char* key, std::string& value, const std::vector<std::string>& allowed,
             const char*) override {
    known_.push_back(key);
    const YAML::Node n = node_[key];
    if (!n) return;
    if (!n.IsScalar()) bad(key, n, "a single value");
    const std::string v = n.Scalar();
    bool ok = allowed.empty();
    for (const auto& a : allowed) ok = ok || a == v;
    if (!ok) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      bad(key, n, "one of: " + list);
    }
    value = v;
  }
  void field(const char* key, std::vector<int>&, int, int, const char*) override {
    known_.push_back(key);
  }
  const std::vector<std::string>& known() const { return known_; }

 private:
  static bool as_number(const YAML::Node& n, double& out) {
    if (!n.IsScalar()) return false;
    const std::string& s = n.Scalar();
    char* end = nullptr;
    out = std::strtod(s.c_str(), &end);
    return !s.empty() && end && *end == '\0' && std::isfinite(out);
  }
  [[noreturn]] void bad(const char* key, const YAML::Node& n, const std::string& allowed) {
    const std::string v = n.IsScalar() ? n.Scalar() : std::string("(not a scalar)");
    throw std::runtime_error(path_ + ": " + key + ": value '" + v + "' is not allowed; expected " +
                             allowed);
  }
  const YAML::Node& node_;
  const std::string& path_;
  std::vector<std::string> known_;
};

}  // namespace

CameraModel read_camera_yaml(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error(path + ": cannot read camera file");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (!root.IsMap()) throw std::runtime_error(path + ": expected a mapping of camera keys");
  for (const char* required : {"width", "height", "fx", "fy", "cx", "cy"}) {
    if (!root[required]) {
      throw std::runtime_error(path + ": missing key '" + required +
                               "' (required: width, height, fx, fy, cx, cy)");
    }
  }
  CameraModel cam;
  cam.k1 = cam.k2 = cam.p1 = cam.p2 = cam.k3 = cam.k4 = 0.0;
  YamlCameraReader reader(root, path);
  cam.visit(reader);
  for (const auto& kv : root) {
    const std::string k = kv.first.as<std::string>();
    if (std::find(reader.known().begin(), reader.known().end(), k) == reader.known().end()) {
      std::string list;
      for (const auto& a : reader.known()) list += (list.empty() ? "" : ", ") + a;
      throw std::runtime_error(path + ": unknown key '" + k + "'; allowed: " + list);
    }
  }
  const std::string err = cam.validate();
  if (!err.empty()) throw std::runtime_error(path + ": " + err);
  return cam;
}

void write_camera_yaml(const std::string& path, const CameraModel& c) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  std::fprintf(f,
               "# Camera intrinsics (rdslam camera.yaml; see docs/sources.md)\n"
               "model: %s\nwidth: %d\nheight: %d\n"
               "fx: %.17g\nfy: %.17g\ncx: %.17g\ncy: %.17g\n"
               "k1: %.17g\nk2: %.17g\np1: %.17g\np2: %.17g\nk3: %.17g\nk4: %.17g\n",
               c.model.c_str(), c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.p1, c.p2,
               c.k3, c.k4);
  const bool ok = std::ferror(f) == 0;
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error(path + ": write failed");
}

bool has_image_extension(const std::string& name) {
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string ext = name.substr(dot + 1);
  for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  for (const char* e : {"png", "jpg", "jpeg", "bmp", "pgm", "ppm", "tif", "tiff"}) {
    if (ext == e) return true;
  }
  return false;
}

bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const bool da = std::isdigit(static_cast<unsigned char>(a[i])) != 0;
    const bool db = std::isdigit(static_cast<unsigned char>(b[j])) != 0;
    if (da && db) {
      // Compare the digit runs by value: skip leading zeros, then by length, then digits.
      size_t ei = i, ej = j;
      while (ei < a.size() && std::isdigit(static_cast<unsigned char>(a[ei]))) ++ei;
      while (ej < b.size() && std::isdigit(static_cast<unsigned char>(b[ej]))) ++ej;
      size_t zi = i, zj = j;
      while (zi + 1 < ei && a[zi] == '0') ++zi;
      while (zj + 1 < ej && b[zj] == '0') ++zj;
      if (ei - zi != ej - zj) return ei - zi < ej - zj;
      const int c = a.compare(zi, ei - zi, b, zj, ej - zj);
      if (c != 0) return c < 0;
      if (ei - i != ej - j) return ei - i < ej - j;  // "01" after "1": deterministic order
      i = ei;
      j = ej;
      continue;
    }
    if (a[i] != b[j]) return a[i] < b[j];
    ++i;
    ++j;
  }
  return a.size() - i < b.size() - j;
}

}  // namespace rdslam
