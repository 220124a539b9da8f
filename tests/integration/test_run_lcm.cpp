// `rdslam run` end to end over LCM (issue 9 acceptance):
// - Debian's lcm-logger records the pose channel while `rdslam run` replays KITTI 06 in
//   real time; the log, decoded with the generated C++ types, holds one rdslam.pose_t per
//   processed frame and every pose equals the ground-truth file (pass-through tracker).
// - A separate Python process (the venv's lcm + the generated Python types) subscribes
//   while the daemon replays EuRoC, like a robot's consumer would.
// - The map epoch and the pose covariance reach a Python subscriber; rdslam.pose_t versions
//   are told apart (tools/lcm/rdslam_msgs.py).
// Each test uses its own ttl=0 URL port, so tests can run in parallel on one host.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/trajectory.h"
#include "rdslam/pose_t.hpp"
#include "rdslam/status_t.hpp"
#include "tests/support/lcm_test_bus.h"

extern char** environ;

namespace {

const std::string kShared = RDSLAM_SHARED_DIR;
const std::string kBinary = RDSLAM_BINARY;

bool exists(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0;
}

std::string find_program(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(ss, dir, ':');) {
    const std::string p = dir + "/" + name;
    if (::access(p.c_str(), X_OK) == 0) return p;
  }
  return "";
}

// Child process with optional stdout/stderr redirected to files.
struct Child {
  pid_t pid = -1;
  bool wait_exit(int timeout_ms, int* status) {
    for (int i = 0; i < timeout_ms / 10; ++i) {
      const pid_t r = ::waitpid(pid, status, WNOHANG);
      if (r == pid) {
        pid = -1;
        return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  }
  void kill_and_reap() {
    if (pid <= 0) return;
    ::kill(pid, SIGKILL);
    int st = 0;
    ::waitpid(pid, &st, 0);
    pid = -1;
  }
  ~Child() { kill_and_reap(); }
};

Child spawn(const std::vector<std::string>& args, const std::string& out_path,
            const std::string& err_path) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  if (!out_path.empty()) {
    posix_spawn_file_actions_addopen(&fa, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  }
  if (!err_path.empty()) {
    posix_spawn_file_actions_addopen(&fa, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  }
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  Child c;
  if (posix_spawn(&c.pid, argv[0], &fa, nullptr, argv.data(), environ) != 0) c.pid = -1;
  posix_spawn_file_actions_destroy(&fa);
  return c;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string temp_dir(const std::string& tag) {
  char tmpl[256];
  std::snprintf(tmpl, sizeof(tmpl), "/tmp/rdslam_%s_XXXXXX", tag.c_str());
  const char* d = ::mkdtemp(tmpl);
  return d ? d : "/tmp";
}

std::vector<std::string> run_args(const std::string& source, const std::string& url,
                                  const std::string& pose_ch, const std::string& status_ch) {
  // Built-in defaults (equal to systemd/rdslam.yaml by rule) plus the test's overrides.
  return {kBinary,       "run",
          "--set",       "source=" + source,
          "--set",       "lcm.url=" + url,
          "--set",       "lcm.pose_channel=" + pose_ch,
          "--set",       "lcm.status_channel=" + status_ch,
          "--set",       "pipeline.replay_speed=1",
          "--set",       "pipeline.stages=passthrough",
          "--log-level", "info"};
}

const std::string kPython = std::string(RDSLAM_SOURCE_DIR) + "/.venv/bin/python";

// Writes `script` to DIR/NAME.py and runs it with the venv's Python and `args`, stdout and
// stderr to DIR/NAME.out and DIR/NAME.err. With `ready`, the script's last argument is a path
// it creates once subscribed, and this waits for it (10 s); pid -1 if it did not start.
Child start_python(const std::string& dir, const std::string& name, const std::string& script,
                   std::vector<std::string> args, bool ready) {
  std::ofstream(dir + "/" + name + ".py") << script;
  args.insert(args.begin(), {kPython, dir + "/" + name + ".py"});
  const std::string ready_path = dir + "/" + name + ".ready";
  if (ready) args.push_back(ready_path);
  Child c = spawn(args, dir + "/" + name + ".out", dir + "/" + name + ".err");
  for (int i = 0; ready && c.pid > 0 && i < 1000 && !exists(ready_path); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (ready && !exists(ready_path)) c.kill_and_reap();
  return c;
}

TEST(RunLcm, LcmLoggerRecordsOnePosePerProcessedFrameEqualToGroundTruth) {
  const std::string kitti = kShared + "/data/kitti06_excerpt";
  if (!exists(kitti + "/poses.txt")) {
    GTEST_SKIP() << "shared data absent: " << kitti << " (needs ../shared/data)";
  }
  const std::string logger = find_program("lcm-logger");
  ASSERT_FALSE(logger.empty()) << "lcm-logger not found: install liblcm-bin "
                                  "(toolchain/install-deps.sh)";
  // A bus and channel prefix of this process only (tests/support/lcm_test_bus.h).
  const std::string url = rdslam::testing::private_lcm_url(1);
  const std::string t1 = rdslam::testing::private_channel("T1");
  const std::string dir = temp_dir("runlcm");
  const std::string log_path = dir + "/poses.lcmlog";

  Child log =
      spawn({logger, "-f", "-c", t1 + "_.*", "--flush-interval=50", "--lcm-url=" + url, log_path},
            dir + "/logger.out", dir + "/logger.err");
  ASSERT_GT(log.pid, 0);
  // Readiness: publish probes until the logger has written one to its file.
  {
    lcm::LCM probe(url);
    ASSERT_TRUE(probe.good());
    const uint8_t byte = 0;
    struct stat st {};
    bool ready = false;
    for (int i = 0; i < 300 && !ready; ++i) {
      probe.publish(t1 + "_PROBE", &byte, 1);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      ready = ::stat(log_path.c_str(), &st) == 0 && st.st_size > 0;
    }
    ASSERT_TRUE(ready) << "lcm-logger did not start recording: " << slurp(dir + "/logger.err");
  }

  Child run =
      spawn(run_args("kitti:" + kitti, url, t1 + "_POSE", t1 + "_STATUS"), "", dir + "/run.err");
  ASSERT_GT(run.pid, 0);
  int status = 0;
  ASSERT_TRUE(run.wait_exit(60000, &status)) << "rdslam run did not finish";
  const std::string run_err = slurp(dir + "/run.err");
  ASSERT_TRUE(WIFEXITED(status)) << run_err;
  ASSERT_EQ(WEXITSTATUS(status), 0) << run_err;

  // Let the logger write the last messages, then stop it the way a user would.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(log.pid, SIGINT);
  int log_status = 0;
  ASSERT_TRUE(log.wait_exit(10000, &log_status));

  lcm::LogFile lf(log_path, "r");
  ASSERT_TRUE(lf.good());
  std::map<int64_t, rdslam::pose_t> poses;  // by seq
  int pose_msgs = 0;
  rdslam::status_t last_status;
  int status_msgs = 0;
  for (const lcm::LogEvent* ev = lf.readNextEvent(); ev; ev = lf.readNextEvent()) {
    if (ev->channel == t1 + "_POSE") {
      rdslam::pose_t m;
      ASSERT_GT(m.decode(ev->data, 0, ev->datalen), 0);
      poses[m.seq] = m;
      ++pose_msgs;
    } else if (ev->channel == t1 + "_STATUS") {
      ASSERT_GT(last_status.decode(ev->data, 0, ev->datalen), 0);
      ++status_msgs;
    }
  }
  ASSERT_GE(status_msgs, 1) << "the final status is always published";
  // One message per processed frame, no duplicates.
  EXPECT_EQ(pose_msgs, static_cast<int>(poses.size()));
  EXPECT_EQ(pose_msgs, static_cast<int>(last_status.frames_processed)) << run_err;
  EXPECT_EQ(last_status.frames_captured, 51);
  EXPECT_EQ(last_status.frames_processed + last_status.frames_dropped, 51);
  std::printf("[ measured ] KITTI 06 real-time replay: %d poses logged, %lld dropped\n", pose_msgs,
              static_cast<long long>(last_status.frames_dropped));

  const rdslam::Trajectory gt =
      rdslam::read_trajectory(kitti + "/poses.txt", rdslam::TrajectoryFormat::kKitti);
  ASSERT_EQ(gt.size(), 51u);
  for (const auto& [seq, m] : poses) {
    ASSERT_GE(seq, 0);
    ASSERT_LT(seq, 51);
    const rdslam::StampedPose& g = gt[static_cast<size_t>(seq)];
    EXPECT_EQ(m.state, int8_t{rdslam::pose_t::STATE_TRACKING}) << seq;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(m.position[i], g.p_world_cam[i], 1e-9) << seq;
    Eigen::Quaterniond q(m.orientation[0], m.orientation[1], m.orientation[2], m.orientation[3]);
    EXPECT_NEAR(q.angularDistance(g.q_world_cam), 0.0, 1e-9) << seq;
    EXPECT_GE(m.latency_us, 0);
  }
}

TEST(RunLcm, SeparatePythonProcessSubscribesWhileThePipelineRuns) {
  const std::string euroc = kShared + "/data/euroc_V1_01_micro";
  if (!exists(euroc + "/mav0/cam0/data.csv")) {
    GTEST_SKIP() << "shared data absent: " << euroc << " (needs ../shared/data)";
  }
  ASSERT_TRUE(exists(kPython)) << "Python venv missing: run toolchain/install-deps.sh";
  const std::string url = rdslam::testing::private_lcm_url(2);
  const std::string t2 = rdslam::testing::private_channel("T2");
  const std::string dir = temp_dir("runpy");
  const std::string script = R"PY(import os, sys, time
sys.path.insert(0, sys.argv[1])
import lcm
from rdslam import pose_t, status_t
url, prefix, ready_path = sys.argv[2], sys.argv[3], sys.argv[4]
lc = lcm.LCM(url)
got = {"poses": 0, "tracking": 0, "seqs": [], "processed": -1, "running_reports": 0}
def on_pose(ch, data):
    m = pose_t.decode(data)
    got["poses"] += 1
    got["seqs"].append(m.seq)
    if m.state == pose_t.STATE_TRACKING:
        got["tracking"] += 1
def on_status(ch, data):
    m = status_t.decode(data)
    got["processed"] = m.frames_processed
    got["running_reports"] += 1
lc.subscribe(prefix + "_POSE", on_pose)
lc.subscribe(prefix + "_STATUS", on_status)
open(ready_path, "w").close()
deadline = time.time() + 60
last = time.time()
while time.time() < deadline:
    if lc.handle_timeout(100) > 0:
        last = time.time()
    elif got["poses"] > 0 and time.time() - last > 1.5:
        break
inorder = all(b > a for a, b in zip(got["seqs"], got["seqs"][1:]))
print(got["poses"], got["tracking"], got["processed"], int(inorder), got["running_reports"])
)PY";
  Child sub = start_python(dir, "sub", script, {RDSLAM_LCM_PY_DIR, url, t2}, true);
  ASSERT_GT(sub.pid, 0) << "subscriber did not start: " << slurp(dir + "/sub.err");

  Child run =
      spawn(run_args("euroc:" + euroc, url, t2 + "_POSE", t2 + "_STATUS"), "", dir + "/run.err");
  int status = 0;
  ASSERT_TRUE(run.wait_exit(60000, &status));
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << slurp(dir + "/run.err");
  int sub_status = 0;
  ASSERT_TRUE(sub.wait_exit(30000, &sub_status));
  ASSERT_TRUE(WIFEXITED(sub_status) && WEXITSTATUS(sub_status) == 0) << slurp(dir + "/sub.err");

  std::istringstream out(slurp(dir + "/sub.out"));
  int poses = -1, tracking = -1, processed = -1, inorder = 0, reports = 0;
  out >> poses >> tracking >> processed >> inorder >> reports;
  EXPECT_EQ(poses, processed) << "one pose per processed frame reached the subscriber";
  EXPECT_EQ(tracking, poses) << "every EuRoC frame has ground truth";
  EXPECT_GE(poses, 1);
  EXPECT_EQ(inorder, 1) << "sequence numbers strictly increasing";
  EXPECT_GE(reports, 2) << "1 Hz status during a 4.7 s replay, plus the final one";
  std::printf("[ measured ] EuRoC real-time replay: subscriber got %d poses of %d processed\n",
              poses, processed);
}

// Issue 23 item 8: a Python subscriber in its own process, decoding with
// tools/lcm/rdslam_msgs.py, while `rdslam run` tracks (the real SLAM stages, lossless replay) a
// synthetic scene whose image goes black for 36 frames: the tracker loses its two-keyframe map,
// re-initializes, and the messages' map_epoch goes 0 -> 1. Every TRACKING / RELOCALIZED pose
// carries a covariance (finite, symmetric, positive definite), every other pose all -1.
TEST(RunLcm, PythonSubscriberSeesTheMapEpochChangeAndThePoseCovariance) {
  ASSERT_TRUE(exists(kPython)) << "Python venv missing: run toolchain/install-deps.sh";
  const std::string url = rdslam::testing::private_lcm_url(4);
  const std::string t4 = rdslam::testing::private_channel("T4");
  const std::string dir = temp_dir("runepoch");
  const std::string script = R"PY(import math, sys, time
sys.path[:0] = [sys.argv[1], sys.argv[2]]
import lcm, numpy as np
import rdslam_msgs
url, prefix, ready_path = sys.argv[3], sys.argv[4], sys.argv[5]
lc = lcm.LCM(url)
msgs = []
lc.subscribe(prefix + "_POSE", lambda ch, data: msgs.append(rdslam_msgs.decode_pose(data)))
open(ready_path, "w").close()
deadline, last = time.time() + 120, time.time()
while time.time() < deadline:
    if lc.handle_timeout(100) > 0:
        last = time.time()
    elif msgs and time.time() - last > 3.0:
        break
msgs.sort(key=lambda m: m.seq)
tracked = {0: 0, 1: 0}
cov_ok = cov_bad = untracked = untracked_bad = decreases = 0
sig_c, sig_r = [], []
for prev, m in zip([None] + msgs[:-1], msgs):
    if prev is not None and m.map_epoch < prev.map_epoch:
        decreases += 1
    C = np.array(m.covariance).reshape(6, 6)
    if m.state in (m.STATE_TRACKING, m.STATE_RELOCALIZED):
        tracked[m.map_epoch] = tracked.get(m.map_epoch, 0) + 1
        good = (np.all(np.isfinite(C)) and np.allclose(C, C.T, rtol=0, atol=1e-12 * abs(C).max())
                and np.all(np.diag(C) > 0) and np.linalg.eigvalsh(C).min() > 0)
        cov_ok += int(good)
        cov_bad += int(not good)
        if good:
            sig_c.append(math.sqrt(np.trace(C[:3, :3])))
            sig_r.append(math.degrees(math.sqrt(np.trace(C[3:, 3:]))))
    else:
        untracked += 1
        untracked_bad += int(not np.all(C == -1.0))
epochs = sorted(set(m.map_epoch for m in msgs))
print(len(msgs), ",".join(str(e) for e in epochs), tracked[0], tracked[1], cov_ok, cov_bad,
      untracked, untracked_bad, decreases, min(m.version for m in msgs),
      np.median(sig_c) if sig_c else -1, np.median(sig_r) if sig_r else -1)
)PY";
  Child sub = start_python(
      dir, "sub", script,
      {RDSLAM_LCM_PY_DIR, std::string(RDSLAM_SOURCE_DIR) + "/tools/lcm", url, t4}, true);
  ASSERT_GT(sub.pid, 0) << "subscriber did not start: " << slurp(dir + "/sub.err");

  std::vector<std::string> args =
      run_args("synth:" + std::string(RDSLAM_SOURCE_DIR) + "/tests/data/lcm/map_reset.yaml", url,
               t4 + "_POSE", t4 + "_STATUS");
  // The SLAM stages, lossless; no keyframes after the initial two, so that losing the map
  // resets it (tracker.reset_after_lost_frames applies to maps of <= 2 keyframes).
  for (const char* kv : {"pipeline.stages=slam", "pipeline.replay_speed=0",
                         "tracker.young_map_keyframes=0", "tracker.max_keyframe_interval=100000",
                         "tracker.m1=1", "tracker.keyframe_overlap_ratio=0"}) {
    args.push_back("--set");
    args.push_back(kv);
  }
  Child run = spawn(args, "", dir + "/run.err");
  int status = 0;
  ASSERT_TRUE(run.wait_exit(120000, &status));
  const std::string run_err = slurp(dir + "/run.err");
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << run_err;
  EXPECT_NE(run_err.find("re-initializing"), std::string::npos) << run_err;
  int sub_status = 0;
  ASSERT_TRUE(sub.wait_exit(60000, &sub_status));
  ASSERT_TRUE(WIFEXITED(sub_status) && WEXITSTATUS(sub_status) == 0) << slurp(dir + "/sub.err");

  std::istringstream out(slurp(dir + "/sub.out"));
  int poses = -1, tracked0 = -1, tracked1 = -1, cov_ok = -1, cov_bad = -1, untracked = -1;
  int untracked_bad = -1, decreases = -1, version = -1;
  std::string epochs;
  double sig_c = -1, sig_r = -1;
  out >> poses >> epochs >> tracked0 >> tracked1 >> cov_ok >> cov_bad >> untracked >>
      untracked_bad >> decreases >> version >> sig_c >> sig_r;
  ASSERT_GE(poses, 100) << "of 120 frames; lossless replay, ttl=0 multicast on this host";
  EXPECT_EQ(version, 2);
  EXPECT_EQ(epochs, "0,1") << "one map reset";
  EXPECT_EQ(decreases, 0) << "map_epoch never goes back";
  EXPECT_GE(tracked0, 10) << "tracked in the first map";
  EXPECT_GE(tracked1, 10) << "tracked in the second map";
  EXPECT_EQ(cov_ok, tracked0 + tracked1) << "every tracked pose has a covariance";
  EXPECT_EQ(cov_bad, 0);
  EXPECT_GE(untracked, 30) << "LOST and INITIALIZING frames";
  EXPECT_EQ(untracked_bad, 0) << "untracked poses: covariance all -1";
  std::printf(
      "[ measured ] map_reset over LCM: %d poses, tracked %d (epoch 0) + %d (epoch 1), %d "
      "untracked; median sqrt(trace) of the centre covariance %.4g map units, rotation %.4g "
      "deg\n",
      poses, tracked0, tracked1, untracked, sig_c, sig_r);
}

// Issue 23 item 8: rdslam.pose_t versions. LCM's fingerprint already makes a subscriber of
// one version refuse another's messages; tools/lcm/rdslam_msgs.py makes the refusal say which
// versions met. Over LCM (ttl=0) in a separate Python process: a version 1 message (types
// generated from tests/data/lcm/rdslam_pose_t_v1.lcm, the old definition) and a hypothetical
// version 3 one are rejected by decode_pose() with errors naming both fingerprints and versions;
// version 2 decodes; an old subscriber (version 1 types) cannot decode version 2 either: a
// ValueError, never a silently misread pose.
TEST(RunLcm, PoseDecoderNamesBothVersionsOnAFingerprintMismatch) {
  ASSERT_TRUE(exists(kPython)) << "Python venv missing: run toolchain/install-deps.sh";
  const std::string lcm_gen = find_program("lcm-gen");
  ASSERT_FALSE(lcm_gen.empty()) << "lcm-gen not found: install liblcm-bin";
  const std::string dir = temp_dir("posever");
  const std::string data = std::string(RDSLAM_SOURCE_DIR) + "/tests/data/lcm/";
  for (const char* v : {"v1", "v3"}) {
    Child gen =
        spawn({lcm_gen, "--python", "--ppath", dir + "/" + v, data + "rdslam_pose_t_" + v + ".lcm"},
              "", dir + "/gen.err");
    int st = 0;
    ASSERT_TRUE(gen.wait_exit(20000, &st));
    ASSERT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0) << slurp(dir + "/gen.err");
  }
  const std::string script = R"PY(import importlib.util, sys
sys.path[:0] = [sys.argv[1], sys.argv[2]]
import lcm
import rdslam_msgs
from rdslam import pose_t

def load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.pose_t

old = load(sys.argv[3] + "/v1/rdslam/pose_t.py", "pose_t_v1")
new3 = load(sys.argv[3] + "/v3/rdslam/pose_t.py", "pose_t_v3")
m3 = new3()
m3.version = new3.VERSION
m2 = pose_t()
m2.version, m2.map_epoch, m2.seq = pose_t.VERSION, 5, 9
lc = lcm.LCM(sys.argv[4])
got = []
lc.subscribe(sys.argv[5], lambda ch, data: got.append(data))
for m in (old(), m3, m2):
    lc.publish(sys.argv[5], m.encode())
while len(got) < 3 and lc.handle_timeout(2000) > 0:
    pass
print("received", len(got))
for data in got:
    try:
        m = rdslam_msgs.decode_pose(data)
        print("decoded version %d epoch %d seq %d" % (m.version, m.map_epoch, m.seq))
    except rdslam_msgs.VersionMismatch as e:
        print("mismatch %s %s: %s" % (e.message_version, e.expected_version, e))
    try:
        old.decode(data)
        print("old subscriber decoded")
    except ValueError as e:
        print("old subscriber ValueError: %s" % e)
)PY";
  Child py = start_python(
      dir, "versions", script,
      {RDSLAM_LCM_PY_DIR, std::string(RDSLAM_SOURCE_DIR) + "/tools/lcm", dir,
       rdslam::testing::private_lcm_url(5), rdslam::testing::private_channel("T5_POSE")},
      false);
  int st = 0;
  ASSERT_TRUE(py.wait_exit(30000, &st));
  ASSERT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0) << slurp(dir + "/versions.err");
  const std::string out = slurp(dir + "/versions.out");
  std::istringstream lines(out);
  std::vector<std::string> l;
  for (std::string s; std::getline(lines, s);) l.push_back(s);
  ASSERT_EQ(l.size(), 7u) << out;
  EXPECT_EQ(l[0], "received 3");
  char v2[32];
  std::snprintf(v2, sizeof(v2), "0x%016llx",
                static_cast<unsigned long long>(::rdslam::pose_t::getHash()));
  // Version 1 (the fingerprint rdslam published until this change) to a version 2 subscriber.
  EXPECT_EQ(l[1].rfind("mismatch 1 2: rdslam.pose_t version mismatch: message fingerprint "
                       "0x9e8a9bc1e75bdc76, expected " +
                           std::string(v2) +
                           " (version 2): the message is version 1, from an "
                           "older rdslam",
                       0),
            0u)
      << l[1];
  EXPECT_EQ(l[2], "old subscriber decoded") << "version 1 to version 1";
  EXPECT_EQ(l[3].rfind("mismatch 3 2: rdslam.pose_t version mismatch: message fingerprint 0x", 0),
            0u)
      << l[3];
  EXPECT_NE(l[3].find(", expected " + std::string(v2) +
                      " (version 2): the message is version 3, from a newer rdslam"),
            std::string::npos)
      << l[3];
  EXPECT_EQ(l[4], "old subscriber ValueError: Decode error");
  EXPECT_EQ(l[5], "decoded version 2 epoch 5 seq 9");
  EXPECT_EQ(l[6], "old subscriber ValueError: Decode error") << "version 2 to version 1: loud";
}

// The daemon on a long recording (80 s of video): SIGTERM, as systemd sends it, stops every
// thread within 2 s and the process exits 0.
TEST(RunLcm, SigtermStopsTheDaemonCleanlyWithinTwoSeconds) {
  const std::string video = kShared + "/data/opencv_vtest/vtest.avi";
  if (!exists(video)) GTEST_SKIP() << "shared data absent: " << video;
  const std::string dir = temp_dir("runterm");
  Child run = spawn(run_args("video:" + video, rdslam::testing::private_lcm_url(3),
                             rdslam::testing::private_channel("T3_POSE"),
                             rdslam::testing::private_channel("T3_STATUS")),
                    "", dir + "/run.err");
  ASSERT_GT(run.pid, 0);
  // Running: the first periodic stats line has been logged.
  bool running = false;
  for (int i = 0; i < 3000 && !running; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    running = slurp(dir + "/run.err").find("stats: ") != std::string::npos;
  }
  ASSERT_TRUE(running) << slurp(dir + "/run.err");
  ::kill(run.pid, SIGTERM);
  int status = 0;
  const bool exited = run.wait_exit(2000, &status);
  const std::string err = slurp(dir + "/run.err");
  ASSERT_TRUE(exited) << "rdslam run did not stop within 2 s of SIGTERM\n" << err;
  ASSERT_TRUE(WIFEXITED(status)) << err;
  EXPECT_EQ(WEXITSTATUS(status), 0) << err;
  EXPECT_NE(err.find("SIGTERM received"), std::string::npos) << err;
  EXPECT_NE(err.find("run: stopped after"), std::string::npos) << err;
}

}  // namespace
