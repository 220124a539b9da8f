#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/timestamp.h"
#include "core/trajectory.h"

namespace fs = std::filesystem;
using namespace rdslam;

namespace {

class TrajectoryFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("rdslam_test_trajectory_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  // Expects read_trajectory to throw a runtime_error whose message names file and line.
  void expect_error(const std::string& path, TrajectoryFormat f, int line, const char* what) {
    try {
      read_trajectory(path, f);
      FAIL() << "no error for " << what;
    } catch (const std::runtime_error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(path + ":" + std::to_string(line) + ":"), std::string::npos)
          << what << ": " << msg;
    }
  }
  fs::path dir_;
};

}  // namespace

TEST(Timestamp, ParsesExactNanoseconds) {
  int64_t ns = 0;
  ASSERT_TRUE(parse_seconds_ns("1403715273.262142976", ns));
  EXPECT_EQ(ns, 1403715273262142976LL);  // not representable through double
  ASSERT_TRUE(parse_seconds_ns("1305031102.175304", ns));
  EXPECT_EQ(ns, 1305031102175304000LL);
  ASSERT_TRUE(parse_seconds_ns("12", ns));
  EXPECT_EQ(ns, 12000000000LL);
  ASSERT_TRUE(parse_seconds_ns(".5", ns));
  EXPECT_EQ(ns, 500000000LL);
  ASSERT_TRUE(parse_seconds_ns("-0.000000001", ns));
  EXPECT_EQ(ns, -1);
  ASSERT_TRUE(parse_seconds_ns("0.0000000015", ns));  // 10th digit rounds
  EXPECT_EQ(ns, 2);
  for (const char* bad : {"", ".", "-", "1e9", "1.2.3", "abc", "1 ", "99999999999"}) {
    EXPECT_FALSE(parse_seconds_ns(bad, ns)) << bad;
  }
}

TEST(Timestamp, FormatParseRoundTripsEveryValue) {
  for (int64_t v : {int64_t{0}, int64_t{1}, int64_t{-1}, int64_t{999999999},
                    int64_t{1403715273262142976LL}, int64_t{-1403715273262142976LL},
                    std::numeric_limits<int64_t>::max(), std::numeric_limits<int64_t>::min()}) {
    int64_t back = 0;
    const std::string s = format_seconds_ns(v);
    ASSERT_TRUE(parse_seconds_ns(s, back)) << s;
    EXPECT_EQ(back, v) << s;
  }
  EXPECT_EQ(format_seconds_ns(1403715273262142976LL), "1403715273.262142976");
  EXPECT_EQ(format_seconds_ns(-1), "-0.000000001");
}

TEST_F(TrajectoryFiles, ReadsTum) {
  const auto path = write("gt.txt",
                          "# ground truth trajectory\n"
                          "# timestamp tx ty tz qx qy qz qw\n"
                          "1305031102.175304 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n"
                          "\n"
                          "1305031102.185304\t1.3 0.6 1.6 0 0 0 1\r\n");
  const Trajectory t = read_trajectory(path, TrajectoryFormat::kTum);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].stamp_ns, 1305031102175304000LL);
  EXPECT_DOUBLE_EQ(t[0].p_world_cam.x(), 1.3405);
  EXPECT_DOUBLE_EQ(t[0].p_world_cam.z(), 1.6575);
  // TUM order is qx qy qz qw; stored normalized.
  const double n = std::sqrt(0.6574 * 0.6574 + 0.6126 * 0.6126 + 0.2949 * 0.2949 + 0.3248 * 0.3248);
  EXPECT_NEAR(t[0].q_world_cam.x(), 0.6574 / n, 1e-12);
  EXPECT_NEAR(t[0].q_world_cam.w(), -0.3248 / n, 1e-12);
  EXPECT_EQ(t[1].stamp_ns, 1305031102185304000LL);
  EXPECT_DOUBLE_EQ(t[1].q_world_cam.w(), 1.0);
  EXPECT_EQ(detect_trajectory_format(path), TrajectoryFormat::kTum);
}

TEST_F(TrajectoryFiles, ReadsEurocAndIgnoresExtraColumns) {
  const auto path = write(
      "data.csv",
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
      "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
      "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
      "b_a_RS_S_z [m s^-2]\n"
      "1403715273262142976,0.878895,2.1834,0.948427,0.069433,-0.824237,-0.106942,-0.551702,"
      "0.0015,0.0017,-0.0023,-0.0022,0.0215,0.0770,-0.0180,0.0659,0.0309\n"
      "1403715273312143104, 1, 2, 3, 1, 0, 0, 0\n");
  const Trajectory t = read_trajectory(path, TrajectoryFormat::kEuroc);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].stamp_ns, 1403715273262142976LL);
  EXPECT_DOUBLE_EQ(t[0].p_world_cam.y(), 2.1834);
  // EuRoC order is qw qx qy qz.
  EXPECT_NEAR(t[0].q_world_cam.w(), 0.069433, 1e-5);
  EXPECT_NEAR(t[0].q_world_cam.x(), -0.824237, 1e-5);
  EXPECT_NEAR(t[0].q_world_cam.z(), -0.551702, 1e-5);
  EXPECT_NEAR(t[0].q_world_cam.norm(), 1.0, 1e-12);
  EXPECT_EQ(t[1].stamp_ns, 1403715273312143104LL);
  EXPECT_DOUBLE_EQ(t[1].p_world_cam.z(), 3.0);
  EXPECT_EQ(detect_trajectory_format(path), TrajectoryFormat::kEuroc);
}

TEST_F(TrajectoryFiles, ReadsKittiAsTWorldCam) {
  // Frame 0 identity; frame 1 rotated 90 deg about y (camera turns right) and moved forward.
  const auto path = write("poses.txt",
                          "1 0 0 0 0 1 0 0 0 0 1 0\n"
                          "0 0 1 0.5 0 1 0 -0.25 -1 0 0 2.0\n");
  const Trajectory t = read_trajectory(path, TrajectoryFormat::kKitti, 50000000);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].stamp_ns, 0);
  EXPECT_EQ(t[1].stamp_ns, 50000000);
  EXPECT_TRUE(t[0].q_world_cam.isApprox(Eigen::Quaterniond::Identity()));
  EXPECT_TRUE(t[1].p_world_cam.isApprox(Eigen::Vector3d(0.5, -0.25, 2.0)));
  // The camera's z axis (column 2 of R_world_cam) points along world +x.
  const Eigen::Vector3d z_in_world = t[1].q_world_cam * Eigen::Vector3d::UnitZ();
  EXPECT_TRUE(z_in_world.isApprox(Eigen::Vector3d::UnitX(), 1e-12)) << z_in_world.transpose();
  EXPECT_EQ(detect_trajectory_format(path), TrajectoryFormat::kKitti);
}

TEST_F(TrajectoryFiles, TumWriteReadRoundTripIsExact) {
  Trajectory in;
  for (int i = 0; i < 5; ++i) {
    StampedPose p;
    p.stamp_ns = 1403715273262142976LL + i * 50000001LL;
    p.p_world_cam = Eigen::Vector3d(0.1 * i + 1e-9, -2.0 / 3.0, 1e6 + i);
    p.q_world_cam =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * i + 0.1, Eigen::Vector3d(1, 2, 3).normalized()));
    in.push_back(p);
  }
  const std::string path = (dir_ / "out.txt").string();
  write_trajectory_tum(path, in);
  const Trajectory out = read_trajectory(path, TrajectoryFormat::kTum);
  ASSERT_EQ(out.size(), in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    EXPECT_EQ(out[i].stamp_ns, in[i].stamp_ns);
    EXPECT_EQ(out[i].p_world_cam, in[i].p_world_cam);  // %.17g is exact
    EXPECT_NEAR(out[i].q_world_cam.angularDistance(in[i].q_world_cam), 0.0, 1e-12);
  }
}

TEST_F(TrajectoryFiles, MalformedInputNamesFileAndLine) {
  expect_error(write("a.txt", "# c\n1.0 0 0 0 0 0 0 1\n1.1 0 0 0 0 0 1\n"), TrajectoryFormat::kTum,
               3, "TUM with 7 values");
  expect_error(write("b.txt", "1.0 0 0 x 0 0 0 1\n"), TrajectoryFormat::kTum, 1, "TUM non-number");
  expect_error(write("c.txt", "1.0 0 0 0 0 0 0 nan\n"), TrajectoryFormat::kTum, 1, "TUM nan");
  expect_error(write("d.txt", "1.0 0 0 0 1 2 3 4\n"), TrajectoryFormat::kTum, 1,
               "TUM non-unit quaternion");
  expect_error(write("e.txt", "abc 0 0 0 0 0 0 1\n"), TrajectoryFormat::kTum, 1, "TUM bad stamp");
  expect_error(write("f.csv", "#h\n\n1.5,0,0,0,1,0,0,0\n"), TrajectoryFormat::kEuroc, 3,
               "EuRoC fractional ns");
  expect_error(write("g.csv", "1,0,0,0,1,0,0\n"), TrajectoryFormat::kEuroc, 1, "EuRoC 7 columns");
  expect_error(write("h.csv", "1,0,0,0,1,0,0,0,zz\n"), TrajectoryFormat::kEuroc, 1,
               "EuRoC bad extra column");
  expect_error(write("i.txt", "1 0 0 0 0 1 0 0 0 0 1\n"), TrajectoryFormat::kKitti, 1,
               "KITTI 11 values");
  expect_error(write("j.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n"),
               TrajectoryFormat::kKitti, 2, "KITTI non-rotation");
  expect_error(write("k.txt", "1 0 0 0 0 1 0 0 0 0 -1 0\n"), TrajectoryFormat::kKitti, 1,
               "KITTI reflection");
}

TEST_F(TrajectoryFiles, DetectRejectsUnknownShapes) {
  EXPECT_THROW(detect_trajectory_format(write("a.txt", "1 2 3\n")), std::runtime_error);
  EXPECT_THROW(detect_trajectory_format(write("b.txt", "# only a comment\n")), std::runtime_error);
  EXPECT_THROW(detect_trajectory_format(write("c.csv", "1,2,3\n")), std::runtime_error);
  EXPECT_THROW(detect_trajectory_format((dir_ / "missing.txt").string()), std::runtime_error);
  EXPECT_THROW(read_trajectory((dir_ / "missing.txt").string(), TrajectoryFormat::kTum),
               std::runtime_error);
}

TEST(TrajectoryShared, ReadsEurocAndTumGroundTruthOfTheSameSequence) {
  const std::string dir = std::string(RDSLAM_SHARED_DIR) + "/data/euroc_V1_01_micro";
  const std::string csv = dir + "/mav0/state_groundtruth_estimate0/data.csv";
  const std::string tum = dir + "/groundtruth_tum_vicon2gt.txt";
  if (!fs::exists(csv) || !fs::exists(tum)) {
    GTEST_SKIP() << "shared data not found at " << dir << " (../shared/data is absent)";
  }
  EXPECT_EQ(detect_trajectory_format(csv), TrajectoryFormat::kEuroc);
  EXPECT_EQ(detect_trajectory_format(tum), TrajectoryFormat::kTum);
  const Trajectory a = read_trajectory(csv, TrajectoryFormat::kEuroc);
  const Trajectory b = read_trajectory(tum, TrajectoryFormat::kTum);
  ASSERT_EQ(a.size(), 2895u);  // SOURCE.md: whole sequence at 20 Hz
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a[0].stamp_ns, 1403715273262142976LL);
  for (size_t i = 0; i < a.size(); i += 97) {
    // The TUM copy has 5 decimals in seconds and 6 in values.
    EXPECT_NEAR(static_cast<double>(a[i].stamp_ns - b[i].stamp_ns), 0.0, 1e4) << i;
    EXPECT_LT((a[i].p_world_cam - b[i].p_world_cam).norm(), 1e-5) << i;
    EXPECT_LT(a[i].q_world_cam.angularDistance(b[i].q_world_cam), 1e-5) << i;
  }
}

TEST(TrajectoryShared, ReadsKittiPoses) {
  const std::string path = std::string(RDSLAM_SHARED_DIR) + "/data/kitti06_excerpt/poses.txt";
  if (!fs::exists(path)) {
    GTEST_SKIP() << "shared data not found: " << path << " (../shared/data is absent)";
  }
  EXPECT_EQ(detect_trajectory_format(path), TrajectoryFormat::kKitti);
  const Trajectory t = read_trajectory(path, TrajectoryFormat::kKitti);
  ASSERT_EQ(t.size(), 51u);
  EXPECT_EQ(t[50].stamp_ns, 5000000000LL);
  // SOURCE.md: frame 1 t = (-0.01402, -0.02820, 1.19900); ~59.9 m of forward driving.
  EXPECT_NEAR(t[1].p_world_cam.x(), -0.01401751, 1e-8);
  EXPECT_NEAR(t[1].p_world_cam.z(), 1.198998, 1e-6);
  double length = 0;
  for (size_t i = 1; i < t.size(); ++i) length += (t[i].p_world_cam - t[i - 1].p_world_cam).norm();
  EXPECT_NEAR(length, 59.9, 0.5);
}
