// `record` then `replay` gives bit-identical frames and timestamps (issue 4, acceptance),
// through the library (TumRecorder + open_source) and through the `rdslam record` command,
// including a clean stop on SIGINT.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "drivers/recorder.h"
#include "drivers/source_factory.h"
#include "tests/support/dataset_fixtures.h"

using namespace rdslam;
using rdslam::testing::random_image;
using rdslam::testing::same_pixels;
using rdslam::testing::TempDir;
namespace fs = std::filesystem;

namespace {

const SourceOptions kDefaults;

// Records `uri` completely into `out` with the library.
void record_all(const std::string& uri, const std::string& out, int max_frames = 1 << 30) {
  auto src = open_source(uri, kDefaults);
  TumRecorder rec(out, uri, src->camera());
  Frame f;
  int n = 0;
  while (n < max_frames && src->read(f, 1000) == SourceStatus::kOk) {
    ASSERT_TRUE(rec.write(f));
    ++n;
  }
  rec.close();
  EXPECT_EQ(rec.written(), static_cast<uint64_t>(n));
  EXPECT_EQ(rec.failures(), 0u);
}

void expect_identical(const std::string& a_uri, const std::string& b_uri, size_t max_frames,
                      size_t expect_frames) {
  std::vector<cv::Mat> fa, fb;
  std::vector<int64_t> sa, sb;
  {
    auto a = open_source(a_uri, kDefaults);
    Frame f;
    while (fa.size() < max_frames && a->read(f, 1000) == SourceStatus::kOk) {
      fa.push_back(f.image.clone());
      sa.push_back(f.stamp_ns);
    }
  }
  auto b = open_source(b_uri, kDefaults);
  rdslam::testing::read_all(*b, fb, sb);
  ASSERT_EQ(fa.size(), expect_frames);
  ASSERT_EQ(fb.size(), fa.size());
  for (size_t i = 0; i < fa.size(); ++i) {
    EXPECT_TRUE(same_pixels(fa[i], fb[i])) << "frame " << i;
    EXPECT_EQ(sa[i], sb[i]) << "frame " << i;
  }
}

// A TUM folder of `n` colour frames, 9-decimal stamps at ~30 Hz.
void make_tum(const TempDir& d, const std::string& rel, int n) {
  std::string list = "# timestamp filename\n";
  for (int i = 0; i < n; ++i) {
    const int64_t ns = 1700000000123456789LL + i * 33333337LL;
    char stamp[40];
    std::snprintf(stamp, sizeof(stamp), "%lld.%09lld", static_cast<long long>(ns / 1000000000),
                  static_cast<long long>(ns % 1000000000));
    const std::string name = std::string("rgb/") + stamp + ".png";
    rdslam::testing::write_png(d.path() / rel / name, random_image(48, 32, CV_8UC3, 900 + i));
    list += std::string(stamp) + " " + name + "\n";
  }
  d.write(rel + "/rgb.txt", list);
  d.write(rel + "/camera.yaml", "width: 48\nheight: 32\nfx: 40\nfy: 40\ncx: 24\ncy: 16\n");
}

int run(const std::vector<std::string>& args, std::string* output = nullptr) {
  std::string cmd = RDSLAM_BINARY;
  for (const auto& a : args) cmd += " '" + a + "'";
  cmd += " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return -1;
  char buf[512];
  std::string out;
  while (fgets(buf, sizeof(buf), p)) out += buf;
  const int st = pclose(p);
  if (output) *output = out;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

}  // namespace

TEST(Recorder, RecordThenReplayIsBitIdenticalColour) {
  TempDir d;
  make_tum(d, "src", 6);
  record_all("tum:" + d.str("src"), d.str("out"));
  expect_identical("tum:" + d.str("src"), "tum:" + d.str("out"), 100, 6);
  // The recording is a complete dataset: its camera.yaml carries the intrinsics in effect.
  EXPECT_DOUBLE_EQ(open_source(d.str("out"), kDefaults)->camera()->fx, 40.0);
}

TEST(Recorder, RecordThenReplayIsBitIdenticalGrey) {
  TempDir d;
  for (int i = 0; i < 5; ++i) {
    rdslam::testing::write_png(d.path() / "imgs" / ("f" + std::to_string(i) + ".png"),
                               random_image(40, 30, CV_8UC1, 50 + i));
  }
  record_all("images:" + d.str("imgs") + "?fps=7", d.str("out"));
  expect_identical("images:" + d.str("imgs") + "?fps=7", d.str("out"), 100, 5);
  auto replay = open_source(d.str("out"), kDefaults);
  EXPECT_EQ(replay->info().format, PixelFormat::kGray8);
}

TEST(Recorder, RecordThenReplayOfRealFootage) {
  const std::string euroc = std::string(RDSLAM_SHARED_DIR) + "/data/euroc_V1_01_micro";
  const std::string vtest = std::string(RDSLAM_SHARED_DIR) + "/data/opencv_vtest/vtest.avi";
  if (!fs::exists(euroc) || !fs::exists(vtest)) {
    GTEST_SKIP() << "shared data not found in " << RDSLAM_SHARED_DIR
                 << "/data (../shared/data is absent)";
  }
  TempDir d;
  record_all("euroc:" + euroc, d.str("euroc"), 10);
  expect_identical("euroc:" + euroc, d.str("euroc"), 10, 10);
  record_all("video:" + vtest, d.str("vtest"), 10);
  expect_identical("video:" + vtest, d.str("vtest"), 10, 10);
}

TEST(Recorder, RefusesToOverwrite) {
  TempDir d;
  d.write("full/something.txt", "keep me");
  EXPECT_THROW(TumRecorder(d.str("full"), "x", std::nullopt), std::runtime_error);
  d.write("file", "x");
  EXPECT_THROW(TumRecorder(d.str("file"), "x", std::nullopt), std::runtime_error);
  fs::create_directories(d.path() / "empty");
  EXPECT_NO_THROW(TumRecorder(d.str("empty"), "x", std::nullopt));
  std::ifstream keep(d.str("full/something.txt"));
  std::string text;
  std::getline(keep, text);
  EXPECT_EQ(text, "keep me");
}

TEST(Recorder, DuplicateStampsDoNotOverwriteFrames) {
  TempDir d;
  TumRecorder rec(d.str("out"), "x", std::nullopt);
  Frame f;
  f.stamp_ns = 42;
  for (int i = 0; i < 3; ++i) {
    f.image = random_image(16, 16, CV_8UC1, i);
    f.seq = static_cast<uint64_t>(i);
    ASSERT_TRUE(rec.write(f));
  }
  rec.close();
  auto src = open_source("tum:" + d.str("out"), kDefaults);
  std::vector<cv::Mat> frames;
  std::vector<int64_t> stamps;
  rdslam::testing::read_all(*src, frames, stamps);
  ASSERT_EQ(frames.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(same_pixels(frames[i], random_image(16, 16, CV_8UC1, i)));
}

TEST(RecordCommand, StopsCleanlyOnSigintWithEverythingIntact) {
  TempDir d;
  make_tum(d, "src", 90);  // 3 s at 30 fps, replayed in real time
  const std::string out = d.str("out");
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string src = "tum:" + d.str("src");
    execl(RDSLAM_BINARY, RDSLAM_BINARY, "record", "--source", src.c_str(), "--out", out.c_str(),
          "--speed", "1", static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until some frames are on disk, then interrupt.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < deadline) {
    std::ifstream list(out + "/rgb.txt");
    int lines = 0;
    for (std::string l; std::getline(list, l);) lines += l.empty() || l[0] == '#' ? 0 : 1;
    if (lines >= 5) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(kill(pid, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  // Stopped early, nothing half-written, and what is there replays exactly.
  for (const auto& e : fs::directory_iterator(out + "/rgb")) {
    EXPECT_NE(e.path().extension(), ".tmp") << e.path();
  }
  std::vector<cv::Mat> frames;
  std::vector<int64_t> stamps;
  auto rec = open_source("tum:" + out, kDefaults);
  rdslam::testing::read_all(*rec, frames, stamps);
  ASSERT_GE(frames.size(), 5u);
  ASSERT_LT(frames.size(), 90u);
  EXPECT_EQ(rec->counters().faults, 0u);
  expect_identical("tum:" + d.str("src"), "tum:" + out, frames.size(), frames.size());

  // A second recording into the same folder is refused and leaves it untouched.
  std::string msg;
  EXPECT_EQ(run({"record", "--source", "tum:" + d.str("src"), "--out", out}, &msg), 1);
  EXPECT_NE(msg.find("refusing to overwrite"), std::string::npos) << msg;
  auto again = open_source("tum:" + out, kDefaults);
  EXPECT_EQ(again->info().frame_count, static_cast<int64_t>(frames.size()));
}

TEST(RecordCommand, SecondsLimitAndUsageErrors) {
  TempDir d;
  make_tum(d, "src", 90);
  std::string msg;
  ASSERT_EQ(run({"record", "--source", "tum:" + d.str("src"), "--out", d.str("out"), "--speed", "1",
                 "--seconds", "0.5"},
                &msg),
            0)
      << msg;
  EXPECT_NE(msg.find("--seconds reached"), std::string::npos) << msg;
  auto rec = open_source("tum:" + d.str("out"), kDefaults);
  // 0.5 s at 30 fps: about 15 frames; generous bounds, this is not a timing test.
  EXPECT_GE(rec->info().frame_count, 3);
  EXPECT_LT(rec->info().frame_count, 90);
  EXPECT_EQ(run({"record", "--source", "tum:" + d.str("src")}, &msg), 2) << msg;  // no --out
  EXPECT_EQ(run({"record", "--source", d.str("nothing"), "--out", d.str("o2")}, &msg), 1) << msg;
}
