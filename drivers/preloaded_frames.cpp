#include "drivers/preloaded_frames.h"

#include <utility>

namespace rdslam {

namespace {
constexpr int kMaxPreloadFailures = 1000;
}  // namespace

PreloadedFrames::PreloadedFrames(FrameSource& src)
    : info_(src.info()), camera_(src.camera()), ground_truth_(src.ground_truth()) {
  int failures = 0;
  for (;;) {
    Frame f;
    const SourceStatus s = src.read(f, 1000);
    if (s == SourceStatus::kEndOfStream) break;
    if (s != SourceStatus::kOk) {
      if (++failures > kMaxPreloadFailures) break;
      continue;
    }
    bytes_ += f.image.total() * f.image.elemSize();
    // A deep copy: a source may fill the frame with a view of its own buffer.
    f.image = f.image.clone();
    frames_.push_back(std::move(f));
  }
  info_.frame_count = static_cast<int64_t>(frames_.size());
}

SourceStatus PreloadedFrames::Reader::read(Frame& out, int) {
  if (next_ >= p_.frames_.size()) return SourceStatus::kEndOfStream;
  const Frame& f = p_.frames_[next_++];
  f.image.copyTo(out.image);
  out.format = f.format;
  out.stamp_ns = f.stamp_ns;
  out.seq = f.seq;
  out.dataset_index = f.dataset_index;
  out.arrival_mono_ns = mono_now_ns();
  return SourceStatus::kOk;
}

SourceCounters PreloadedFrames::Reader::counters() const {
  SourceCounters c;
  c.delivered = next_;
  return c;
}

}  // namespace rdslam
