// Notifier and WatchdogGate: the watchdog policy on a synthetic clock, and the real
// sd_notify() datagrams on a NOTIFY_SOCKET owned by the test (no systemd needed).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include "firmware_app/sd_notify.h"
#include "tests/support/notify_socket.h"

using rdslam::Notifier;
using rdslam::WatchdogGate;
using rdslam::testing::NotifyMessage;
using rdslam::testing::NotifySocket;
using Action = WatchdogGate::Action;

namespace {
constexpr int64_t kMs = 1000000;  // ns per ms
}

TEST(WatchdogGate, DisabledNeverPings) {
  WatchdogGate g(0);
  g.arm(0, 0);
  for (int i = 1; i < 100; ++i) EXPECT_EQ(g.poll(i * 1000 * kMs, i), Action::kNone);
}

TEST(WatchdogGate, UnarmedNeverPings) {
  WatchdogGate g(1000000);  // 1 s
  EXPECT_FALSE(g.armed());
  EXPECT_EQ(g.poll(10000 * kMs, 42), Action::kNone);
}

TEST(WatchdogGate, PingsEveryHalfIntervalWhileProgressAdvances) {
  WatchdogGate g(1000000);  // 1 s interval -> ping period 500 ms
  EXPECT_EQ(g.period_ns(), 500 * kMs);
  g.arm(0, 0);
  int pings = 0;
  uint64_t frames = 0;
  int64_t last_ping = 0;
  // 30 fps for 5 s, polled every 10 ms.
  for (int64_t t = 0; t <= 5000 * kMs; t += 10 * kMs) {
    frames = static_cast<uint64_t>(t / (33 * kMs));
    const Action a = g.poll(t, frames);
    EXPECT_NE(a, Action::kWithheld) << "at " << t / kMs << " ms";
    if (a == Action::kPing) {
      ++pings;
      if (pings > 1) {
        EXPECT_EQ(t - last_ping, 500 * kMs);
      }
      last_ping = t;
    }
  }
  EXPECT_EQ(pings, 10);
}

TEST(WatchdogGate, NoPingBeforeHalfIntervalEvenWithProgress) {
  WatchdogGate g(2000000);  // 2 s
  g.arm(0, 0);
  EXPECT_EQ(g.poll(999 * kMs, 50), Action::kNone);
  EXPECT_EQ(g.poll(1000 * kMs, 51), Action::kPing);
  EXPECT_EQ(g.poll(1001 * kMs, 52), Action::kNone);
}

TEST(WatchdogGate, StalledProgressWithholdsPingsUntilItResumes) {
  WatchdogGate g(1000000);
  g.arm(0, 10);
  EXPECT_EQ(g.poll(500 * kMs, 20), Action::kPing);
  // Tracker stalls at 20 frames: every due ping is withheld, for as long as it lasts.
  for (int64_t t = 1000 * kMs; t <= 4000 * kMs; t += 100 * kMs) {
    EXPECT_EQ(g.poll(t, 20), Action::kWithheld) << "at " << t / kMs << " ms";
  }
  // Progress again: the next poll pings at once (the ping is overdue).
  EXPECT_EQ(g.poll(4050 * kMs, 21), Action::kPing);
  EXPECT_EQ(g.poll(4100 * kMs, 22), Action::kNone);
}

TEST(WatchdogGate, NoProgressSinceArmIsNotLiveness) {
  WatchdogGate g(1000000);
  g.arm(0, 7);
  EXPECT_EQ(g.poll(600 * kMs, 7), Action::kWithheld);
}

// Sets/unsets the notify environment for one test and restores it afterwards.
class NotifierEnv : public ::testing::Test {
 protected:
  void SetUp() override { clear(); }
  void TearDown() override { clear(); }
  static void clear() {
    unsetenv("NOTIFY_SOCKET");
    unsetenv("WATCHDOG_USEC");
    unsetenv("WATCHDOG_PID");
  }
};

TEST_F(NotifierEnv, WithoutNotifySocketEverythingIsANoOp) {
  setenv("WATCHDOG_USEC", "1000000", 1);  // a watchdog without a socket cannot be fed
  Notifier n;
  EXPECT_FALSE(n.active());
  EXPECT_EQ(n.watchdog_usec(), 0u);
  EXPECT_EQ(n.tick_period_ms(), 1000);
  n.ready("running", 0, 0);
  n.status("tracking");
  EXPECT_EQ(n.tick(10000 * kMs, 100), Action::kNone);
  n.stopping("bye");
  EXPECT_EQ(n.pings_sent(), 0u);
  EXPECT_EQ(n.send_failures(), 0u);
}

TEST_F(NotifierEnv, SendsReadyStatusWatchdogStoppingDatagrams) {
  NotifySocket sock;
  setenv("NOTIFY_SOCKET", sock.path().c_str(), 1);
  setenv("WATCHDOG_USEC", "400000", 1);  // 0.4 s -> ping period 0.2 s
  setenv("WATCHDOG_PID", std::to_string(getpid()).c_str(), 1);
  Notifier n;
  ASSERT_TRUE(n.active());
  EXPECT_EQ(n.watchdog_usec(), 400000u);
  EXPECT_EQ(n.tick_period_ms(), 20);

  NotifyMessage m;
  n.ready("tracking, 0.0 fps", 0, 0);
  ASSERT_TRUE(sock.receive(m, 1000));
  EXPECT_TRUE(m.has("READY=1")) << m.text;
  EXPECT_EQ(m.value("STATUS"), "tracking, 0.0 fps");

  // Not due yet: nothing is sent.
  EXPECT_EQ(n.tick(100 * kMs, 3), Action::kNone);
  EXPECT_FALSE(sock.receive(m, 50));
  // Due with progress: exactly one WATCHDOG=1.
  EXPECT_EQ(n.tick(200 * kMs, 6), Action::kPing);
  ASSERT_TRUE(sock.receive(m, 1000));
  EXPECT_EQ(m.text, "WATCHDOG=1");
  // Due without progress: withheld, nothing on the socket.
  EXPECT_EQ(n.tick(400 * kMs, 6), Action::kWithheld);
  EXPECT_FALSE(sock.receive(m, 50));
  EXPECT_EQ(n.pings_sent(), 1u);

  // A status with a newline cannot smuggle in another assignment.
  n.status("lost\nREADY=1");
  ASSERT_TRUE(sock.receive(m, 1000));
  EXPECT_FALSE(m.has("READY=1")) << m.text;
  EXPECT_EQ(m.value("STATUS"), "lost READY=1");

  n.stopping("stopping: SIGTERM");
  ASSERT_TRUE(sock.receive(m, 1000));
  EXPECT_TRUE(m.has("STOPPING=1")) << m.text;
  EXPECT_EQ(m.value("STATUS"), "stopping: SIGTERM");
  EXPECT_EQ(n.send_failures(), 0u);
}

TEST_F(NotifierEnv, WatchdogForAnotherPidIsIgnored) {
  NotifySocket sock;
  setenv("NOTIFY_SOCKET", sock.path().c_str(), 1);
  setenv("WATCHDOG_USEC", "400000", 1);
  setenv("WATCHDOG_PID", std::to_string(getpid() + 1).c_str(), 1);
  Notifier n;
  EXPECT_TRUE(n.active());
  EXPECT_EQ(n.watchdog_usec(), 0u);
  n.ready("ok", 0, 0);
  NotifyMessage m;
  ASSERT_TRUE(sock.receive(m, 1000));
  EXPECT_EQ(n.tick(10000 * kMs, 99), Action::kNone);
  EXPECT_FALSE(sock.receive(m, 50));
}

TEST_F(NotifierEnv, InvalidWatchdogValueTurnsWatchdogOff) {
  NotifySocket sock;
  setenv("NOTIFY_SOCKET", sock.path().c_str(), 1);
  setenv("WATCHDOG_USEC", "soon", 1);
  Notifier n;
  EXPECT_EQ(n.watchdog_usec(), 0u);
}

TEST_F(NotifierEnv, VanishedSocketIsCountedNotFatal) {
  std::string path;
  {
    NotifySocket sock;
    path = sock.path();
  }  // socket closed and unlinked
  setenv("NOTIFY_SOCKET", path.c_str(), 1);
  setenv("WATCHDOG_USEC", "400000", 1);
  Notifier n;
  n.ready("ok", 0, 0);
  EXPECT_EQ(n.tick(300 * kMs, 1), Action::kPing);
  n.stopping("bye");
  EXPECT_EQ(n.send_failures(), 3u);
  EXPECT_EQ(n.pings_sent(), 0u);
}
