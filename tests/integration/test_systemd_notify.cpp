// The real daemon (`rdslam run`) under a fake systemd: the test owns the NOTIFY_SOCKET (an
// AF_UNIX datagram socket, what systemd gives a Type=notify service), sets WATCHDOG_USEC and
// WATCHDOG_PID as systemd does, and drives the frame source itself: the daemon reads
// bot_core.image_t from an LCM channel (source lcm:CHANNEL on a ttl=0 URL) that the test
// publishes at 30 Hz, or stops publishing to stall the tracker as a dead camera would.
//
// Checked: READY=1 once frames flow; STATUS= once a second with state and fps; WATCHDOG=1
// every WatchdogSec/2 while frames are processed and NEVER while they are not (so systemd
// would restart the service), resuming when frames return; STOPPING=1 on SIGTERM; exit 0.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bot_core/image_t.hpp"
#include "tests/support/lcm_test_bus.h"
#include "tests/support/notify_socket.h"

using rdslam::testing::NotifyMessage;
using rdslam::testing::NotifySocket;

namespace {

constexpr int kWatchdogUsec = 1000000;  // WatchdogSec=1s: pings due every 0.5 s
constexpr double kWatchdogS = kWatchdogUsec * 1e-6;

// `rdslam run` as systemd would start it, fed by an LCM camera the test controls.
class Daemon {
 public:
  explicit Daemon(const std::string& notify_socket) {
    const int id = static_cast<int>(getpid());
    // A port and channels of our own: parallel tests never see each other's traffic.
    url_ = rdslam::testing::private_lcm_url();
    channel_ = rdslam::testing::private_channel("RDSLAM_NOTIFYTEST_CAM");
    log_path_ = "/tmp/rdslam-notifytest-" + std::to_string(id) + ".log";
    const std::string suffix = "_NOTIFYTEST_" + std::to_string(id);
    std::vector<std::string> args = {
        RDSLAM_BINARY, "run",
        "--config",    std::string(RDSLAM_SOURCE_DIR) + "/systemd/rdslam.yaml",
        "--set",       "source=lcm:" + channel_,
        "--set",       "lcm.url=" + url_,
        "--set",       "lcm.pose_channel=RDSLAM_POSE" + suffix,
        "--set",       "lcm.status_channel=RDSLAM_STATUS" + suffix,
        "--set",       "camera.width=160",
        "--set",       "camera.height=120",
        "--set",       "camera.fx=100",
        "--set",       "camera.fy=100",
        "--set",       "camera.cx=79.5",
        "--set",       "camera.cy=59.5",
    };
    // Fork before any thread exists in this process, so the child may call setenv().
    pid_ = fork();
    if (pid_ == 0) {
      setenv("NOTIFY_SOCKET", notify_socket.c_str(), 1);
      setenv("WATCHDOG_USEC", std::to_string(kWatchdogUsec).c_str(), 1);
      setenv("WATCHDOG_PID", std::to_string(getpid()).c_str(), 1);
      if (!freopen(log_path_.c_str(), "w", stderr)) _exit(126);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    camera_ = std::thread([this] { publish_loop(); });
  }

  ~Daemon() {
    quit_ = true;
    camera_.join();
    if (pid_ > 0 && exit_code_ == kRunning) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    std::remove(log_path_.c_str());
  }

  void set_publishing(bool on) { publishing_ = on; }
  bool alive() {
    poll_exit(0);
    return exit_code_ == kRunning;
  }
  void signal(int sig) { kill(pid_, sig); }
  // Exit code within `timeout_ms`, or kRunning.
  int wait_exit(int timeout_ms) {
    poll_exit(timeout_ms);
    return exit_code_;
  }
  std::string log() const {
    std::ifstream in(log_path_);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  static constexpr int kRunning = -1000;

 private:
  void poll_exit(int timeout_ms) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (exit_code_ == kRunning) {
      int status = 0;
      const pid_t r = waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        break;
      }
      if (std::chrono::steady_clock::now() >= until) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

  // A 160x120 grey camera at 30 Hz; a moving gradient so frames differ.
  void publish_loop() {
    lcm::LCM lcm(url_);
    bot_core::image_t img;
    img.width = 160;
    img.height = 120;
    img.row_stride = 160;
    img.pixelformat = bot_core::image_t::PIXEL_FORMAT_GRAY;
    img.size = img.width * img.height;
    img.data.resize(img.size);
    img.nmetadata = 0;
    auto next = std::chrono::steady_clock::now();
    for (int n = 0; !quit_; ++n) {
      next += std::chrono::milliseconds(33);
      std::this_thread::sleep_until(next);
      if (!publishing_ || !lcm.good()) continue;
      for (int i = 0; i < img.size; ++i) img.data[i] = static_cast<uint8_t>(i % 160 + n);
      img.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
      lcm.publish(channel_, &img);
    }
  }

  std::string url_, channel_, log_path_;
  pid_t pid_ = -1;
  int exit_code_ = kRunning;
  std::atomic<bool> publishing_{true};
  std::atomic<bool> quit_{false};
  std::thread camera_;
};

// Reads datagrams until one satisfies `pred` or `timeout_ms` passes; every datagram read is
// appended to `seen`. Returns the index of the match in `seen`, or -1.
template <class Pred>
int wait_for(NotifySocket& sock, int timeout_ms, std::vector<NotifyMessage>& seen, Pred pred) {
  const double until = sock.elapsed_s() + timeout_ms * 1e-3;
  for (double now = sock.elapsed_s(); now < until; now = sock.elapsed_s()) {
    NotifyMessage m;
    if (!sock.receive(m, static_cast<int>((until - now) * 1e3) + 1)) continue;
    seen.push_back(m);
    if (pred(m)) return static_cast<int>(seen.size()) - 1;
  }
  return -1;
}

std::vector<double> watchdog_times(const std::vector<NotifyMessage>& msgs) {
  std::vector<double> t;
  for (const auto& m : msgs) {
    if (m.has("WATCHDOG=1")) t.push_back(m.t_s);
  }
  return t;
}

std::string dump(const std::vector<NotifyMessage>& msgs) {
  std::string s;
  for (const auto& m : msgs) {
    char t[32];
    std::snprintf(t, sizeof(t), "%7.3f  ", m.t_s);
    std::string text = m.text;
    std::replace(text.begin(), text.end(), '\n', '|');
    s += t + text + "\n";
  }
  return s;
}

// Start the daemon and wait for READY=1 (start-up includes LCM and the first frames).
int wait_ready(NotifySocket& sock, Daemon& d, std::vector<NotifyMessage>& seen) {
  const int i =
      wait_for(sock, 20000, seen, [](const NotifyMessage& m) { return m.has("READY=1"); });
  EXPECT_GE(i, 0) << "no READY=1; datagrams:\n" << dump(seen) << "daemon log:\n" << d.log();
  // Before READY only STATUS= lines ("starting: ...") are allowed: no premature ping.
  for (int k = 0; k < i; ++k) EXPECT_FALSE(seen[k].has("WATCHDOG=1")) << dump(seen);
  return i;
}

}  // namespace

TEST(SystemdNotify, ReadyStatusPeriodicWatchdogAndStoppingOnSigterm) {
  NotifySocket sock;
  Daemon d(sock.path());
  std::vector<NotifyMessage> seen;
  const int ready = wait_ready(sock, d, seen);
  ASSERT_GE(ready, 0);
  EXPECT_NE(seen[ready].value("STATUS"), "") << "READY=1 comes with a STATUS= line";

  // Three seconds of frames: pings every WatchdogSec/2, STATUS= once a second.
  const double t_ready = seen[ready].t_s;
  const std::vector<NotifyMessage> run = sock.collect(3000);
  const std::vector<double> pings = watchdog_times(run);
  EXPECT_GE(pings.size(), 4u) << dump(run);  // expected 6 at 0.5 s
  EXPECT_LE(pings.size(), 8u) << dump(run);  // not a ping per frame
  double prev = t_ready, max_gap = 0;
  for (double t : pings) {
    max_gap = std::max(max_gap, t - prev);
    prev = t;
  }
  EXPECT_LT(max_gap, 0.8 * kWatchdogS) << "a ping came too late for systemd:\n" << dump(run);
  int status_lines = 0;
  for (const auto& m : run) {
    const std::string s = m.value("STATUS");
    if (s.empty()) continue;
    ++status_lines;
    EXPECT_NE(s.find(" fps"), std::string::npos) << s;
    EXPECT_TRUE(s.find("TRACKING") != std::string::npos ||
                s.find("INITIALIZING") != std::string::npos ||
                s.find("LOST") != std::string::npos || s.find("RELOCALIZED") != std::string::npos)
        << "STATUS= names the tracking state: " << s;
  }
  EXPECT_GE(status_lines, 2) << dump(run);
  EXPECT_LE(status_lines, 4) << dump(run);
  for (const auto& m : run) EXPECT_FALSE(m.has("READY=1")) << "READY=1 is sent once";

  // SIGTERM: STOPPING=1 at once, clean exit 0 within the unit's TimeoutStopSec.
  d.signal(SIGTERM);
  std::vector<NotifyMessage> stop;
  const int i =
      wait_for(sock, 3000, stop, [](const NotifyMessage& m) { return m.has("STOPPING=1"); });
  EXPECT_GE(i, 0) << dump(stop) << d.log();
  EXPECT_EQ(d.wait_exit(5000), 0) << d.log();
}

TEST(SystemdNotify, StalledTrackerStopsWatchdogPingsUntilFramesReturn) {
  NotifySocket sock;
  Daemon d(sock.path());
  std::vector<NotifyMessage> seen;
  ASSERT_GE(wait_ready(sock, d, seen), 0);
  const std::vector<NotifyMessage> flowing = sock.collect(1500);
  EXPECT_GE(watchdog_times(flowing).size(), 2u) << dump(flowing);

  // The camera stops delivering: the tracker makes no progress. At most the ping already
  // earned by the last frames may still come (within half an interval plus a tick); after
  // that, none for the whole stall, far longer than WatchdogSec (systemd would restart).
  d.set_publishing(false);
  const double t_stall = sock.elapsed_s();
  const std::vector<NotifyMessage> stalled = sock.collect(3500);
  int late_pings = 0, status_lines = 0;
  std::string last_status;
  for (const auto& m : stalled) {
    if (m.has("WATCHDOG=1") && m.t_s > t_stall + 0.5 * kWatchdogS + 0.2) ++late_pings;
    if (!m.value("STATUS").empty()) {
      ++status_lines;
      last_status = m.value("STATUS");
    }
  }
  EXPECT_EQ(late_pings, 0) << "stall began at " << t_stall << " s:\n" << dump(stalled);
  // The daemon itself is alive and says why: the pings stop because of the gate, not
  // because the process hung or died.
  EXPECT_TRUE(d.alive()) << d.log();
  EXPECT_GE(status_lines, 2) << dump(stalled);
  EXPECT_EQ(last_status.rfind("stalled", 0), 0u) << last_status;
  EXPECT_NE(d.log().find("withholding WATCHDOG=1"), std::string::npos) << d.log();

  // Frames return: pings resume.
  d.set_publishing(true);
  std::vector<NotifyMessage> resumed;
  EXPECT_GE(
      wait_for(sock, 3000, resumed, [](const NotifyMessage& m) { return m.has("WATCHDOG=1"); }), 0)
      << dump(resumed) << d.log();

  d.signal(SIGTERM);
  std::vector<NotifyMessage> stop;
  EXPECT_GE(wait_for(sock, 3000, stop, [](const NotifyMessage& m) { return m.has("STOPPING=1"); }),
            0)
      << dump(stop);
  EXPECT_EQ(d.wait_exit(5000), 0) << d.log();
}
