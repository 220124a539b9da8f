// systemd readiness and liveness notification for `rdslam run` (sd_notify(3), Type=notify
// with WatchdogSec= in systemd/rdslam.service).
//
// Notifier wraps libsystemd's sd_notify() and sd_watchdog_enabled(): READY=1 once frames
// flow, STATUS= with state and fps, WATCHDOG=1 and STOPPING=1. Outside systemd (no
// NOTIFY_SOCKET in the environment) every call is a cheap no-op, so the daemon behaves the
// same when started from a shell; a test can hand it a NOTIFY_SOCKET of its own.
//
// The watchdog is gated on real progress (WatchdogGate): a ping is sent at most every half
// WATCHDOG_USEC and only when the progress counter (frames processed by the tracker) has
// advanced since the previous ping. A tracker that hangs, or a camera that stops delivering,
// therefore stops the pings and systemd restarts the service (Restart=on-failure); a thread
// that is merely alive is not enough.
//
// Ownership: one Notifier per process, owned by the thread that supervises the pipeline.
// Threads: not thread-safe; call every method from that one thread. The progress counter is
// passed by value (the caller reads its atomic). No heap allocation after construction.
#pragma once

#include <cstdint>

namespace rdslam {

// The watchdog policy alone, without I/O, so it can be tested with a synthetic clock.
class WatchdogGate {
 public:
  enum class Action : uint8_t {
    kNone = 0,      // no ping due yet (less than half the interval since the last one)
    kPing = 1,      // send WATCHDOG=1 now
    kWithheld = 2,  // a ping is due but progress has not advanced: deliberately not sent
  };

  // interval_us: the watchdog interval (WATCHDOG_USEC); 0 disables the watchdog.
  explicit WatchdogGate(uint64_t interval_us = 0) : interval_us_(interval_us) {}

  // Starts the clock: the first ping is due half an interval after `now_ns` and needs
  // progress beyond `progress`. Call when the pipeline is running (READY=1).
  void arm(int64_t now_ns, uint64_t progress);
  // What to do at `now_ns` (CLOCK_MONOTONIC) given the current progress counter. Returns
  // kPing at most once per half interval and only when `progress` differs from its value at
  // the previous ping (or at arm()); records the ping. Never kPing when disabled or unarmed.
  Action poll(int64_t now_ns, uint64_t progress);

  bool enabled() const { return interval_us_ > 0; }
  bool armed() const { return armed_; }
  uint64_t interval_us() const { return interval_us_; }
  // Nanoseconds between pings while progress flows: half the interval, as sd_watchdog_enabled(3)
  // recommends, so one late ping still arrives before systemd's deadline.
  int64_t period_ns() const { return static_cast<int64_t>(interval_us_) * 500; }

 private:
  uint64_t interval_us_ = 0;
  bool armed_ = false;
  int64_t last_ping_ns_ = 0;
  uint64_t last_progress_ = 0;
};

class Notifier {
 public:
  // Reads NOTIFY_SOCKET and the watchdog settings (WATCHDOG_USEC, WATCHDOG_PID) from the
  // environment through sd_watchdog_enabled(); the watchdog is off unless systemd (or a
  // test) enabled it for this very process.
  Notifier();

  // True when NOTIFY_SOCKET is set, i.e. someone listens to the notifications.
  bool active() const { return active_; }
  uint64_t watchdog_usec() const { return gate_.interval_us(); }
  // Longest the caller may wait between tick() calls without delaying a ping by more than a
  // tenth of the ping period: the supervision loop waits min(own period, this).
  int tick_period_ms() const;

  // READY=1 together with STATUS=`status`; arms the watchdog gate with the current
  // progress. Call once, when the source delivered its first frame and the pipeline runs.
  void ready(const char* status, int64_t now_ns, uint64_t progress);
  // STATUS=`text` (one line, shown by `systemctl status rdslam`). Truncated to 200 bytes.
  void status(const char* text);
  // Watchdog step: sends WATCHDOG=1 when WatchdogGate says kPing. Returns the gate's action
  // so the caller can log a withheld ping (stalled tracker) once.
  WatchdogGate::Action tick(int64_t now_ns, uint64_t progress);
  // STOPPING=1 with a final STATUS=; call when shutdown begins (SIGTERM or end of stream).
  void stopping(const char* status);

  // CLOCK_MONOTONIC in nanoseconds: the clock tick(), ready() and WatchdogGate expect.
  static int64_t clock_ns();

  uint64_t pings_sent() const { return pings_sent_; }
  // sd_notify() calls that failed (socket gone, permission); counted, never fatal.
  uint64_t send_failures() const { return send_failures_; }

 private:
  // Sends one notification datagram; counts failures. `text` is "KEY=VALUE\n...".
  bool send(const char* text);

  bool active_ = false;
  WatchdogGate gate_;
  uint64_t pings_sent_ = 0;
  uint64_t send_failures_ = 0;
};

}  // namespace rdslam
