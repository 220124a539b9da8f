#include "drivers/synth_source.h"

#include <stdexcept>

#include "drivers/replay_source.h"
#include "drivers/synth_sequence.h"

namespace rdslam {

namespace {

// The synthetic camera as a RecordedSequence: ReplaySource supplies the FrameSource
// contract and the pacing (speed 0: as fast as read; X: real time scaled by X).
class SynthRecordedSequence : public RecordedSequence {
 public:
  explicit SynthRecordedSequence(std::unique_ptr<SynthSequence> seq) : seq_(std::move(seq)) {}
  bool stamp(int64_t index, int64_t& stamp_ns) const override {
    if (index < 0 || index >= seq_->frame_count()) return false;
    stamp_ns = seq_->stamp_ns(static_cast<int>(index));
    return true;
  }
  SourceStatus load(int64_t index, cv::Mat& image) override {
    if (index < 0 || index >= seq_->frame_count()) return SourceStatus::kEndOfStream;
    if (!seq_->render(static_cast<int>(index), frame_)) return SourceStatus::kFault;
    // The caller's buffer is reused when sized; copyTo does not allocate then.
    frame_.image.copyTo(image);
    return SourceStatus::kOk;
  }

 private:
  std::unique_ptr<SynthSequence> seq_;
  SynthFrame frame_;
};

}  // namespace

std::unique_ptr<FrameSource> open_synth_source(const std::string& spec_in,
                                               const SourceOptions& options, int frames,
                                               int64_t seed) {
  std::string spec = spec_in;
  if (spec.rfind("synth:", 0) == 0) spec = spec.substr(6);
  if (spec.empty()) throw std::runtime_error("source 'synth:': no scenario given");
  auto seq = std::make_unique<SynthSequence>(spec, frames, seed);
  SourceInfo info;
  info.uri = "synth:" + spec;
  info.kind = "synth";
  info.width = seq->camera().width;
  info.height = seq->camera().height;
  info.format = PixelFormat::kBgr8;
  info.nominal_fps = seq->fps();
  info.frame_count = seq->frame_count();
  const CameraModel camera = seq->camera();
  const Trajectory gt = seq->ground_truth();
  return std::make_unique<ReplaySource>(std::make_unique<SynthRecordedSequence>(std::move(seq)),
                                        info, camera, gt, options.speed);
}

}  // namespace rdslam
