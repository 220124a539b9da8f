// `rdslam eval` as a user runs it: text and JSON output, the plot, usage errors and exit
// codes (0 ok, 1 cannot evaluate, 2 usage).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

namespace fs = std::filesystem;

namespace {

std::string run(const std::string& args, int* status) {
  const std::string cmd = std::string(RDSLAM_BINARY) + " eval " + args + " 2>&1";
  std::string out;
  FILE* f = popen(cmd.c_str(), "r");
  if (!f) {
    *status = -1;
    return out;
  }
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof(buf), f)) > 0) out.append(buf, n);
  const int rc = pclose(f);
  *status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  return out;
}

class CmdEval : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("rdslam_cmd_eval_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    // Ground truth: a quarter circle of radius 10 m at 10 Hz in a z-up world, 1 m climb.
    // Estimate: the same, 1 s later in the file's clock, shifted by (1, 2, 0) and 5 cm off
    // in z on every pose.
    std::ofstream gt(dir_ / "gt.txt");
    std::ofstream est(dir_ / "est.txt");
    for (int k = 0; k <= 40; ++k) {
      const double a = k * M_PI / 80.0;
      const double x = 10 * std::cos(a), y = 10 * std::sin(a), z = 0.025 * k;
      char line[160];
      std::snprintf(line, sizeof(line), "%.3f %.6f %.6f %.6f 0 0 0 1\n", 100.0 + 0.1 * k, x, y, z);
      gt << line;
      std::snprintf(line, sizeof(line), "%.3f %.6f %.6f %.6f 0 0 0 1\n", 100.0 + 0.1 * k, x + 1,
                    y + 2, z + (k % 2 ? 0.05 : -0.05));
      est << line;
    }
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const char* name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

}  // namespace

TEST_F(CmdEval, TextOutputReportsAteAndRpe) {
  int status = 0;
  const std::string out = run(path("gt.txt") + " " + path("est.txt") + " --align none", &status);
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("associated      41 pairs by timestamp"), std::string::npos) << out;
  // No alignment: every pose is off by |(1, 2, +-0.05)| = sqrt(5.0025) = 2.2366269 m.
  EXPECT_NE(out.find("ATE             rmse 2.236627  mean 2.236627  median 2.236627  max "
                     "2.236627 m"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("RPE trans d=1"), std::string::npos) << out;
}

TEST_F(CmdEval, JsonAndPlot) {
  int status = 0;
  const std::string png = path("plot.png");
  const std::string out =
      run(path("gt.txt") + " " + path("est.txt") + " --align none --json --plot " + png, &status);
  ASSERT_EQ(status, 0) << out;
  // No alignment: every pose is off by |(1, 2, +-0.05)| = sqrt(5.0025).
  char expected[64];
  std::snprintf(expected, sizeof(expected), "\"ate_rmse_m\": %.12g", std::sqrt(5.0025));
  EXPECT_NE(out.find(expected), std::string::npos) << out;
  EXPECT_NE(out.find("\"association\": \"time\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"pairs\": 41"), std::string::npos) << out;
  const cv::Mat img = cv::imread(png);
  ASSERT_FALSE(img.empty()) << "no readable PNG at " << png;
  EXPECT_EQ(img.cols, 1200);
  EXPECT_GT(img.rows, 600);
  // Not a blank canvas: the trajectories, axes and text are drawn.
  cv::Mat ink;
  cv::inRange(img, cv::Scalar(0, 0, 0), cv::Scalar(200, 200, 200), ink);
  EXPECT_GT(cv::countNonZero(ink), img.total() / 100);
}

TEST_F(CmdEval, KittiFilesAreAssociatedByIndex) {
  const fs::path poses = fs::path(RDSLAM_SHARED_DIR) / "data/kitti06_excerpt/poses.txt";
  if (!fs::exists(poses)) GTEST_SKIP() << "KITTI excerpt not found at " << poses;
  int status = 0;
  const std::string out = run(poses.string() + " " + poses.string() + " --json", &status);
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("\"association\": \"index\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"pairs\": 51"), std::string::npos) << out;
  const size_t k = out.find("\"ate_rmse_m\": ");
  ASSERT_NE(k, std::string::npos) << out;
  EXPECT_LT(std::strtod(out.c_str() + k + 14, nullptr), 1e-9) << out;
}

TEST_F(CmdEval, UsageErrorsExitWith2) {
  int status = 0;
  std::string out = run(path("gt.txt") + " " + path("est.txt") + " --align affine", &status);
  EXPECT_EQ(status, 2);
  EXPECT_EQ(out,
            "rdslam eval: option '--align': 'affine' is not allowed; allowed sim3, se3, none\n");
  out = run(path("gt.txt"), &status);
  EXPECT_EQ(status, 2);
  EXPECT_EQ(out, "rdslam eval: missing argument ESTIMATE (see --help)\n");
  out = run(path("gt.txt") + " " + path("est.txt") + " --format-gt rosbag", &status);
  EXPECT_EQ(status, 2);
  EXPECT_EQ(out,
            "rdslam eval: option '--format-gt': 'rosbag' is not a trajectory format; allowed "
            "tum, euroc, kitti, auto\n");
  out = run(path("gt.txt") + " " + path("est.txt") + " --rpe-delta 0", &status);
  EXPECT_EQ(status, 2);
  EXPECT_EQ(out, "rdslam eval: option '--rpe-delta': must be a whole number >= 1\n");
}

TEST_F(CmdEval, ImpossibleEvaluationExitsWith1) {
  int status = 0;
  // --max-diff 0 still matches equal stamps; shift the estimate by 50 ms instead.
  std::ofstream(path("late.txt")) << "100.050 0 0 0 0 0 0 1\n100.150 1 0 0 0 0 0 1\n"
                                     "100.250 2 1 0 0 0 0 1\n";
  std::string out = run(path("gt.txt") + " " + path("late.txt"), &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_EQ(out, "rdslam eval: cannot evaluate '" + path("late.txt") + "' against '" +
                     path("gt.txt") +
                     "': no pose of the estimate has a ground-truth stamp within 0.01 s\n");
  out = run(path("gt.txt") + " " + path("absent.txt"), &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_NE(out.find("absent.txt"), std::string::npos) << out;
}
