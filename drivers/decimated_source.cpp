#include "drivers/decimated_source.h"

#include <stdexcept>
#include <string>

namespace rdslam {

namespace {

class DecimatedSource final : public FrameSource {
 public:
  DecimatedSource(std::unique_ptr<FrameSource> inner, int every)
      : inner_(std::move(inner)), every_(every), info_(inner_->info()) {
    info_.uri += " (every " + std::to_string(every) + ")";
    if (info_.frame_count > 0) info_.frame_count = (info_.frame_count + every - 1) / every;
    if (info_.nominal_fps > 0) info_.nominal_fps /= every;
  }

  SourceStatus read(Frame& out, int timeout_ms) override {
    // Skip the every_-1 frames before each kept one (none before the first). A timeout or
    // fault of the inner source is passed on; the skip count resumes on the next call.
    while (to_skip_ > 0) {
      const SourceStatus s = inner_->read(out, timeout_ms);
      if (s != SourceStatus::kOk) return s;
      --to_skip_;
    }
    const SourceStatus s = inner_->read(out, timeout_ms);
    if (s != SourceStatus::kOk) return s;
    to_skip_ = every_ - 1;
    out.seq = next_seq_++;
    return s;
  }

  const SourceInfo& info() const override { return info_; }
  std::optional<CameraModel> camera() const override { return inner_->camera(); }
  std::optional<Trajectory> ground_truth() const override { return inner_->ground_truth(); }
  SourceCounters counters() const override {
    SourceCounters c = inner_->counters();
    c.delivered = next_seq_;
    return c;
  }

 private:
  std::unique_ptr<FrameSource> inner_;
  const int every_;
  SourceInfo info_;
  int to_skip_ = 0;
  uint64_t next_seq_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> make_decimated_source(std::unique_ptr<FrameSource> inner, int every) {
  if (!inner) throw std::runtime_error("--every: no source");
  if (every < 1) throw std::runtime_error("--every: must be an integer >= 1");
  if (every == 1) return inner;  // nothing to decimate: any source, a paced replay included
  if (inner->info().live) {
    throw std::runtime_error("--every: needs a recorded source, not a live one (" +
                             inner->info().uri + ")");
  }
  return std::make_unique<DecimatedSource>(std::move(inner), every);
}

}  // namespace rdslam
