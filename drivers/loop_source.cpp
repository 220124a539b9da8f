#include "drivers/loop_source.h"

#include <stdexcept>
#include <string>
#include <vector>

#include "drivers/replay_source.h"

namespace rdslam {

namespace {

// The cached frames as a RecordedSequence of n * loops frames (ReplaySource paces it).
class LoopedSequence : public RecordedSequence {
 public:
  LoopedSequence(std::vector<cv::Mat> frames, std::vector<int64_t> stamps, int loops,
                 int64_t shift_ns)
      : frames_(std::move(frames)),
        stamps_(std::move(stamps)),
        loops_(loops),
        shift_ns_(shift_ns) {}

  bool stamp(int64_t index, int64_t& stamp_ns) const override {
    const int64_t n = static_cast<int64_t>(frames_.size());
    if (index < 0 || index >= n * loops_) return false;
    stamp_ns = stamps_[index % n] + (index / n) * shift_ns_;
    return true;
  }
  SourceStatus load(int64_t index, cv::Mat& image) override {
    const int64_t n = static_cast<int64_t>(frames_.size());
    if (index < 0 || index >= n * loops_) return SourceStatus::kEndOfStream;
    frames_[index % n].copyTo(image);  // no allocation once `image` has the frame's size
    return SourceStatus::kOk;
  }

 private:
  std::vector<cv::Mat> frames_;
  std::vector<int64_t> stamps_;
  int loops_;
  int64_t shift_ns_;
};

}  // namespace

std::unique_ptr<FrameSource> make_looped_source(std::unique_ptr<FrameSource> inner, int loops,
                                                double speed, size_t max_cache_bytes) {
  if (!inner) throw std::runtime_error("--loop: no source");
  const SourceInfo in = inner->info();
  if (loops < 1) throw std::runtime_error("--loop: must be at least 1");
  if (in.live) throw std::runtime_error("--loop: " + in.uri + " is a live source");
  if (in.frame_count <= 0) {
    throw std::runtime_error("--loop: " + in.uri + " has no known frame count");
  }
  const size_t frame_bytes =
      size_t(in.width) * size_t(in.height) * (in.format == PixelFormat::kBgr8 ? 3 : 1);
  const size_t need = frame_bytes * size_t(in.frame_count);
  if (need > max_cache_bytes) {
    throw std::runtime_error("--loop: caching " + in.uri + " needs " + std::to_string(need >> 20) +
                             " MiB, more than the " + std::to_string(max_cache_bytes >> 20) +
                             " MiB limit; use a shorter sequence");
  }
  const int type = in.format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  std::vector<cv::Mat> frames;
  std::vector<int64_t> stamps;
  frames.reserve(static_cast<size_t>(in.frame_count));
  stamps.reserve(static_cast<size_t>(in.frame_count));
  Frame f;
  for (int64_t i = 0; i < in.frame_count; ++i) {
    f.image.create(in.height, in.width, type);  // read() fills it in place
    SourceStatus s = SourceStatus::kTimeout;
    while (s == SourceStatus::kTimeout || s == SourceStatus::kFault) s = inner->read(f, 1000);
    if (s != SourceStatus::kOk) break;
    frames.push_back(f.image);
    f.image = cv::Mat();  // the next frame gets its own buffer
    stamps.push_back(f.stamp_ns);
  }
  if (frames.empty()) throw std::runtime_error("--loop: " + in.uri + " delivered no frame");
  const int64_t n = static_cast<int64_t>(frames.size());
  const int64_t duration = stamps.back() - stamps.front();
  const int64_t period = n >= 2 ? duration / (n - 1) : int64_t{33333333};
  const int64_t shift = duration + (period > 0 ? period : 1);

  SourceInfo info = in;
  info.uri = in.uri + " (x" + std::to_string(loops) + ")";
  info.frame_count = n * loops;
  std::optional<Trajectory> gt;
  if (const std::optional<Trajectory> g = inner->ground_truth(); g && !g->empty()) {
    Trajectory looped;
    looped.reserve(g->size() * size_t(loops));
    for (int k = 0; k < loops; ++k) {
      for (StampedPose p : *g) {
        p.stamp_ns += k * shift;
        looped.push_back(p);
      }
    }
    gt = std::move(looped);
  }
  const std::optional<CameraModel> camera = inner->camera();
  auto seq = std::make_unique<LoopedSequence>(std::move(frames), std::move(stamps), loops, shift);
  return std::make_unique<ReplaySource>(std::move(seq), std::move(info), camera, std::move(gt),
                                        speed);
}

}  // namespace rdslam
