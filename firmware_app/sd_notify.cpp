#include "firmware_app/sd_notify.h"

#include <systemd/sd-daemon.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>

#include "core/frame_source.h"
#include "core/log.h"

namespace rdslam {
namespace {

// "KEY=<text>" into `out`, with newlines in `text` replaced: a status string must never
// inject further KEY=VALUE assignments into the notification.
void put_assignment(char* out, size_t size, const char* prefix, const char* text) {
  const int n = std::snprintf(out, size, "%s%.200s", prefix, text);
  const size_t start = std::strlen(prefix);
  const size_t end = std::min(size - 1, n > 0 ? static_cast<size_t>(n) : size_t{0});
  for (size_t i = start; i < end; ++i) {
    if (out[i] == '\n') out[i] = ' ';
  }
}

}  // namespace

void WatchdogGate::arm(int64_t now_ns, uint64_t progress) {
  armed_ = true;
  last_ping_ns_ = now_ns;
  last_progress_ = progress;
}

WatchdogGate::Action WatchdogGate::poll(int64_t now_ns, uint64_t progress) {
  if (!enabled() || !armed_) return Action::kNone;
  if (now_ns - last_ping_ns_ < period_ns()) return Action::kNone;
  // Liveness means the tracker processed frames since the last ping, not that this thread
  // still runs: without progress the ping is withheld and systemd's WatchdogSec= expires.
  if (progress == last_progress_) return Action::kWithheld;
  last_ping_ns_ = now_ns;
  last_progress_ = progress;
  return Action::kPing;
}

Notifier::Notifier() {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  active_ = socket != nullptr && socket[0] != '\0';
  uint64_t usec = 0;
  // sd_watchdog_enabled() also checks WATCHDOG_PID, so a watchdog meant for a parent
  // process (e.g. a wrapper script) is not inherited by accident.
  const int r = sd_watchdog_enabled(0, &usec);
  if (r < 0) {
    RDSLAM_LOG_WARN("sd_notify: invalid watchdog environment (%s); watchdog off",
                    std::strerror(-r));
  } else if (r > 0 && active_) {
    gate_ = WatchdogGate(usec);
  }
}

int Notifier::tick_period_ms() const {
  if (!gate_.enabled()) return 1000;
  const int64_t ms = gate_.period_ns() / 10 / 1000000;
  return static_cast<int>(std::clamp<int64_t>(ms, 10, 1000));
}

int64_t Notifier::clock_ns() {
  return mono_now_ns();
}

bool Notifier::send(const char* text) {
  if (!active_) return false;
  const int r = sd_notify(0, text);
  if (r > 0) return true;
  // Counted and logged once: a vanished notify socket must not take the pipeline down.
  if (send_failures_++ == 0) {
    RDSLAM_LOG_WARN("sd_notify: cannot notify (%s)", r < 0 ? std::strerror(-r) : "no socket");
  }
  return false;
}

void Notifier::ready(const char* status, int64_t now_ns, uint64_t progress) {
  char msg[256];
  put_assignment(msg, sizeof(msg), "READY=1\nSTATUS=", status);
  send(msg);
  gate_.arm(now_ns, progress);
  if (gate_.enabled()) {
    RDSLAM_LOG_INFO("sd_notify: ready; watchdog %.1f s, pinging every %.1f s while frames flow",
                    gate_.interval_us() * 1e-6, gate_.period_ns() * 1e-9);
  }
}

void Notifier::status(const char* text) {
  char msg[256];
  put_assignment(msg, sizeof(msg), "STATUS=", text);
  send(msg);
}

WatchdogGate::Action Notifier::tick(int64_t now_ns, uint64_t progress) {
  const WatchdogGate::Action a = gate_.poll(now_ns, progress);
  if (a == WatchdogGate::Action::kPing && send("WATCHDOG=1")) ++pings_sent_;
  return a;
}

void Notifier::stopping(const char* status) {
  char msg[256];
  put_assignment(msg, sizeof(msg), "STOPPING=1\nSTATUS=", status);
  send(msg);
}

}  // namespace rdslam
