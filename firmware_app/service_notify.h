// systemd notifications for a running Pipeline: the glue between the pipeline's observer
// hooks (frames_processed(), status()) and Notifier (firmware_app/sd_notify.h), so that
// `rdslam run` needs only a few lines for issue 11:
//   READY=1     once the source delivered a frame and the tracker processed it;
//   STATUS=...  once a second: tracking state, fps, frames, drops, p99 latency;
//   WATCHDOG=1  every WatchdogSec/2, only while frames_processed() advances;
//   STOPPING=1  when shutdown begins (signal or end of stream), once.
//
// Ownership: borrows the Pipeline, which must outlive it. Threads: the supervising thread of
// `rdslam run` only (the one that calls Pipeline::wait()).
#pragma once

#include <cstdint>

#include "firmware_app/pipeline.h"
#include "firmware_app/sd_notify.h"

namespace rdslam {

class PipelineNotifier {
 public:
  explicit PipelineNotifier(const Pipeline& pipeline);

  // Longest wait between poll() calls (the supervision loop's wait is the smaller of its own
  // period and this).
  int tick_period_ms() const { return notifier_.tick_period_ms(); }
  // One supervision step: READY when due, STATUS once a second, the gated watchdog ping.
  void poll();
  // STOPPING=1 with STATUS="stopping: <reason>"; later calls do nothing.
  void stopping(const char* reason);

  const Notifier& notifier() const { return notifier_; }

 private:
  void send_status(int64_t now_ns);

  const Pipeline& pipeline_;
  Notifier notifier_;
  bool ready_ = false;
  bool stopping_ = false;
  bool stalled_ = false;  // a watchdog ping is being withheld (logged once per stall)
  int64_t start_ns_ = 0;
  int64_t next_status_ns_ = 0;
  int64_t last_progress_ns_ = 0;
  uint64_t last_progress_ = 0;
};

}  // namespace rdslam
