// `rdslam replay --debug-video/--debug-images` through the real threaded pipeline: the debug
// output does not change the tracking result (the TUM trajectories with and without it are
// byte-identical), it writes one video frame per frame and every N-th PNG, and bad output
// paths are usage errors (exit 2, message naming the path) before any frame is processed.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <opencv2/videoio.hpp>

#include "tests/support/run_command.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;
using testing::read_text;
using testing::run_command;
using testing::ScratchDir;
using testing::shell_quote;

const std::string kBin = RDSLAM_BINARY;
// Walking people (outliers on every frame) and an initialization inside 60 frames: a short
// sequence that exercises every kind of marker.
const std::string kSource = "'synth:walking_xyz?frames=60'";

TEST(DebugVideoReplay, SameTrajectoryWithAndWithoutDebugOutput) {
  ScratchDir dir("debug-replay");
  const fs::path plain = dir.path() / "plain.tum", debug = dir.path() / "debug.tum";
  const fs::path video = dir.path() / "out.mp4", images = dir.path() / "img";
  const auto a =
      run_command(kBin + " replay " + kSource + " --trajectory " + shell_quote(plain.string()));
  ASSERT_EQ(a.exit_code, 0) << a.output;
  const auto b =
      run_command(kBin + " replay " + kSource + " --trajectory " + shell_quote(debug.string()) +
                  " --debug-video " + shell_quote(video.string()) + " --debug-images " +
                  shell_quote(images.string()) + " --debug-every 4");
  ASSERT_EQ(b.exit_code, 0) << b.output;
  const std::string ta = read_text(plain), tb = read_text(debug);
  ASSERT_GT(std::count(ta.begin(), ta.end(), '\n'), 20) << "too few tracked frames to compare";
  EXPECT_EQ(ta, tb) << "the debug output changed the trajectory";

  // The summary says what was written; the files are there.
  EXPECT_NE(b.output.find("debug output"), std::string::npos) << b.output;
  cv::VideoCapture cap(video.string(), cv::CAP_FFMPEG);
  ASSERT_TRUE(cap.isOpened());
  int frames = 0;
  for (cv::Mat f; cap.read(f);) ++frames;
  EXPECT_EQ(frames, 15);  // every 4th of 60 frames
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(images)) pngs += e.path().extension() == ".png";
  EXPECT_EQ(pngs, 15);
  EXPECT_TRUE(fs::exists(images / "frame_000000.png"));
  EXPECT_TRUE(fs::exists(images / "frame_000056.png"));
}

TEST(DebugVideoReplay, BadOutputPathsExitTwoNamingThePath) {
  ScratchDir dir("debug-replay-bad");
  const std::string missing = (dir.path() / "no_such_dir" / "out.mp4").string();
  auto r = run_command(kBin + " replay " + kSource + " --debug-video " + shell_quote(missing));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(missing), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("frame 1/"), std::string::npos) << "started replaying: " << r.output;

  const fs::path file = dir.path() / "a_file";
  { std::ofstream(file.string()) << "x"; }
  const std::string under_file = (file / "img").string();
  r = run_command(kBin + " replay " + kSource + " --debug-images " + shell_quote(under_file));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(under_file), std::string::npos) << r.output;

  r = run_command(kBin + " replay " + kSource + " --debug-video " +
                  shell_quote((dir.path() / "v.mp4").string()) + " --debug-every 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--debug-every"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace rdslam
