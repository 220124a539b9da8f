#include "firmware_app/progress.h"

#include <unistd.h>

namespace rdslam {

ProgressSink::ProgressSink(int64_t total, std::FILE* out)
    : ProgressSink(total, out, out && isatty(fileno(out)) == 1) {}

void ProgressSink::on_frame(const FrameResult& r) {
  ++done_;
  if (total_ <= 0 || !out_) return;
  // A realtime replay drops frames, so the last published frame can come before `total`:
  // the percentage follows the source position (dataset index) when it is known.
  const int64_t position = r.dataset_index >= 0 ? r.dataset_index + 1 : done_;
  const int64_t pct = position >= total_ ? 100 : position * 100 / total_;
  const int64_t step = terminal_ ? 1 : 10;
  if (pct / step == shown_ / step && shown_ >= 0) return;
  shown_ = pct;
  if (terminal_) {
    const int width = 40;
    const int filled = static_cast<int>(pct * width / 100);
    char bar[64];
    for (int i = 0; i < width; ++i) bar[i] = i < filled ? '#' : '.';
    bar[width] = '\0';
    std::fprintf(out_, "\r[%s] %3lld%% frame %lld/%lld %-12s", bar, static_cast<long long>(pct),
                 static_cast<long long>(position), static_cast<long long>(total_),
                 to_string(r.result.state));
    if (pct >= 100) std::fprintf(out_, "\n");
  } else {
    std::fprintf(out_, "replay: %3lld%% frame %lld/%lld %s\n", static_cast<long long>(pct),
                 static_cast<long long>(position), static_cast<long long>(total_),
                 to_string(r.result.state));
  }
  std::fflush(out_);
}

}  // namespace rdslam
