#include "firmware_app/service_notify.h"

#include <cstdio>

#include "core/log.h"

namespace rdslam {
namespace {
constexpr int64_t kStatusPeriodNs = 1000000000LL;  // STATUS= once a second
// No frame for this long shows as "stalled" in STATUS= (systemctl status), whether or not
// systemd's watchdog is enabled; well above one frame period of any camera we support.
constexpr int64_t kStalledAfterNs = 2000000000LL;
}  // namespace

PipelineNotifier::PipelineNotifier(const Pipeline& pipeline) : pipeline_(pipeline) {
  start_ns_ = Notifier::clock_ns();
  next_status_ns_ = start_ns_;
  last_progress_ns_ = start_ns_;
}

void PipelineNotifier::poll() {
  if (stopping_) return;
  const int64_t now = Notifier::clock_ns();
  const uint64_t processed = pipeline_.frames_processed();
  if (processed != last_progress_) {
    last_progress_ = processed;
    last_progress_ns_ = now;
  }

  if (!ready_) {
    // READY=1 means "serving": the source delivered a frame and the tracker processed it,
    // so `systemctl start rdslam` returns only once poses are being published.
    if (processed > 0 && pipeline_.running()) {
      ready_ = true;
      char msg[128];
      std::snprintf(msg, sizeof(msg), "running: first frame processed %.1f s after start",
                    (now - start_ns_) * 1e-9);
      notifier_.ready(msg, now, processed);
      next_status_ns_ = now + kStatusPeriodNs;
    } else if (now >= next_status_ns_) {
      notifier_.status("starting: waiting for the first frame from the source");
      next_status_ns_ = now + kStatusPeriodNs;
    }
    return;
  }

  const WatchdogGate::Action a = notifier_.tick(now, processed);
  if (a == WatchdogGate::Action::kWithheld && !stalled_) {
    stalled_ = true;
    RDSLAM_LOG_WARN(
        "watchdog: no frame processed for %.1f s; withholding WATCHDOG=1 so that systemd "
        "restarts rdslam if this lasts WatchdogSec",
        (now - last_progress_ns_) * 1e-9);
  } else if (a == WatchdogGate::Action::kPing && stalled_) {
    stalled_ = false;
    RDSLAM_LOG_INFO("watchdog: frames flow again; pinging");
  }
  if (now >= next_status_ns_) {
    send_status(now);
    next_status_ns_ = now + kStatusPeriodNs;
  }
}

void PipelineNotifier::send_status(int64_t now_ns) {
  const PipelineStatus s = pipeline_.status();
  const auto frames = static_cast<unsigned long long>(last_progress_);
  char msg[200];
  if (now_ns - last_progress_ns_ >= kStalledAfterNs) {
    std::snprintf(msg, sizeof(msg), "stalled: no frame processed for %.0f s (%s, %llu frames)",
                  (now_ns - last_progress_ns_) * 1e-9, to_string(s.state), frames);
  } else {
    std::snprintf(msg, sizeof(msg), "%s, %.1f fps, %llu frames, %llu dropped, p99 latency %.1f ms",
                  to_string(s.state), s.fps, frames,
                  static_cast<unsigned long long>(s.frames_dropped), s.latency_p99_ms);
  }
  notifier_.status(msg);
}

void PipelineNotifier::stopping(const char* reason) {
  if (stopping_) return;
  stopping_ = true;
  char msg[128];
  std::snprintf(msg, sizeof(msg), "stopping: %s", reason);
  notifier_.stopping(msg);
}

}  // namespace rdslam
