#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "drivers/dataset_euroc.h"
#include "drivers/source_factory.h"
#include "tests/support/dataset_fixtures.h"

using namespace rdslam;
using rdslam::testing::random_image;
using rdslam::testing::same_pixels;
using rdslam::testing::TempDir;
namespace fs = std::filesystem;

namespace {

const SourceOptions kDefaults;

// T_BS of the fixture: camera rotated +90 deg about the body z axis, offset (0.1, -0.2, 0.3).
const char* kSensorYaml =
    "%YAML:1.0\n"
    "# General sensor definitions.\n"
    "sensor_type: camera\n"
    "comment: VI-Sensor cam0 (MT9M034)\n"
    "T_BS:\n"
    "  cols: 4\n"
    "  rows: 4\n"
    "  data: [0.0, -1.0, 0.0, 0.1,\n"
    "         1.0, 0.0, 0.0, -0.2,\n"
    "         0.0, 0.0, 1.0, 0.3,\n"
    "         0.0, 0.0, 0.0, 1.0]\n"
    "rate_hz: 20\n"
    "resolution: [40, 30]\n"
    "camera_model: pinhole\n"
    "intrinsics: [45.8, 45.7, 20.2, 14.8] #fu, fv, cu, cv\n"
    "distortion_model: radial-tangential\n"
    "distortion_coefficients: [-0.28, 0.07, 0.0002, 1.7e-05]\n";

struct EurocFixture {
  explicit EurocFixture(const TempDir& d) {
    std::string list = "#timestamp [ns],filename\n";
    for (int i = 0; i < 3; ++i) {
      stamps.push_back(1403715273262142976LL + i * 50000128LL);
      const std::string name = std::to_string(stamps.back()) + ".png";
      images.push_back(random_image(40, 30, CV_8UC1, 7 + i));
      rdslam::testing::write_png(d.path() / "mav0/cam0/data" / name, images.back());
      list += std::to_string(stamps.back()) + "," + name + "\n";
    }
    d.write("mav0/cam0/data.csv", list);
    d.write("mav0/cam0/sensor.yaml", kSensorYaml);
    // Body at (1, 2, 3) rotated 90 deg about world x (q = [cos45, sin45, 0, 0]).
    d.write("mav0/state_groundtruth_estimate0/data.csv",
            "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
            "q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], "
            "b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], "
            "b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n"
            "1403715273262142976,1,2,3,0.70710678118654757,0.70710678118654757,0,0,"
            "0,0,0,0,0,0,0,0,0\n");
  }
  std::vector<cv::Mat> images;
  std::vector<int64_t> stamps;
};

}  // namespace

TEST(DatasetEuroc, FramesCalibrationAndCameraGroundTruth) {
  TempDir d;
  EurocFixture fx(d);
  // The sequence root, the mav0 folder, and a bare path all open the same data.
  for (const std::string& uri : {"euroc:" + d.str(), "euroc:" + d.str("mav0"), d.str()}) {
    auto src = open_source(uri, kDefaults);
    EXPECT_EQ(src->info().kind, "euroc") << uri;
    EXPECT_EQ(src->info().format, PixelFormat::kGray8);
    EXPECT_NEAR(src->info().nominal_fps, 1e9 / 50000128.0, 1e-9);
    std::vector<cv::Mat> frames;
    std::vector<int64_t> stamps;
    rdslam::testing::read_all(*src, frames, stamps);
    ASSERT_EQ(frames.size(), 3u);
    for (size_t i = 0; i < 3; ++i) {
      EXPECT_TRUE(same_pixels(frames[i], fx.images[i]));
      EXPECT_EQ(stamps[i], fx.stamps[i]);
    }
    const auto cam = src->camera();
    ASSERT_TRUE(cam.has_value());
    EXPECT_EQ(cam->width, 40);
    EXPECT_DOUBLE_EQ(cam->fx, 45.8);
    EXPECT_DOUBLE_EQ(cam->cy, 14.8);
    EXPECT_DOUBLE_EQ(cam->k1, -0.28);
    EXPECT_DOUBLE_EQ(cam->p2, 1.7e-05);
    EXPECT_EQ(cam->model, "pinhole-radtan");

    const auto gt = src->ground_truth();
    ASSERT_TRUE(gt.has_value());
    ASSERT_EQ(gt->size(), 1u);
    // T_world_cam = T_world_body * T_body_cam, computed by hand:
    //   R_wb = Rx(90): (x,y,z) -> (x,-z,y); p_cam_in_body = (0.1,-0.2,0.3)
    //   p_world_cam = R_wb * (0.1,-0.2,0.3) + (1,2,3) = (0.1,-0.3,-0.2) + (1,2,3)
    EXPECT_TRUE((*gt)[0].p_world_cam.isApprox(Eigen::Vector3d(1.1, 1.7, 2.8), 1e-12))
        << (*gt)[0].p_world_cam.transpose();
    //   camera x axis = R_wb * R_bc * ex = R_wb * (0,1,0) = (0,0,1)
    const Eigen::Vector3d x_cam_in_world = (*gt)[0].q_world_cam * Eigen::Vector3d::UnitX();
    EXPECT_TRUE(x_cam_in_world.isApprox(Eigen::Vector3d(0, 0, 1), 1e-12))
        << x_cam_in_world.transpose();
    EXPECT_EQ((*gt)[0].stamp_ns, 1403715273262142976LL);
  }
}

TEST(DatasetEuroc, EquidistantModelAndBadCalibration) {
  TempDir d;
  EurocFixture fx(d);
  std::string yaml = kSensorYaml;
  yaml.replace(yaml.find("radial-tangential"), 17, "equidistant");
  yaml.replace(yaml.find("[-0.28, 0.07, 0.0002, 1.7e-05]"), 30, "[0.01, -0.02, 0.03, -0.04]");
  d.write("mav0/cam0/sensor.yaml", yaml);
  const EurocCameraInfo info = read_euroc_camera_yaml(d.str("mav0/cam0/sensor.yaml"));
  EXPECT_EQ(info.camera.model, "pinhole-equidistant");
  EXPECT_DOUBLE_EQ(info.camera.k3, 0.03);
  EXPECT_DOUBLE_EQ(info.camera.k4, -0.04);
  EXPECT_DOUBLE_EQ(info.camera.p1, 0.0);
  EXPECT_DOUBLE_EQ(info.rate_hz, 20.0);

  std::string bad = kSensorYaml;
  bad.replace(bad.find("1.0, 0.0, 0.0, -0.2"), 3, "2.0");  // not a rotation
  d.write("mav0/cam0/sensor.yaml", bad);
  EXPECT_THROW(read_euroc_camera_yaml(d.str("mav0/cam0/sensor.yaml")), std::runtime_error);
  bad = kSensorYaml;
  bad.replace(bad.find("[40, 30]"), 8, "[41, 30]");  // images are 40x30
  d.write("mav0/cam0/sensor.yaml", bad);
  EXPECT_THROW(open_source("euroc:" + d.str(), kDefaults), std::runtime_error);
  // Found by tests/fuzz/fuzz_dataset_index.cpp: a resolution beyond int's range was cast
  // (undefined behaviour); now a clear error naming the key.
  bad = kSensorYaml;
  bad.replace(bad.find("[40, 30]"), 8, "[4e30, 30]");
  d.write("mav0/cam0/sensor.yaml", bad);
  try {
    read_euroc_camera_yaml(d.str("mav0/cam0/sensor.yaml"));
    FAIL() << "resolution 4e30 accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("resolution:"), std::string::npos) << e.what();
  }
  d.write("mav0/cam0/sensor.yaml", kSensorYaml);
  d.write("mav0/cam0/data.csv", "#timestamp [ns],filename\n12.5,a.png\n");
  try {
    open_source("euroc:" + d.str(), kDefaults);
    FAIL() << "fractional ns accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("data.csv:2:"), std::string::npos) << e.what();
  }
}

TEST(DatasetEuroc, DatasetCalibrationBeatsCameraYamlButSetCameraWins) {
  TempDir d;
  EurocFixture fx(d);
  d.write("camera.yaml", "width: 40\nheight: 30\nfx: 99\nfy: 99\ncx: 20\ncy: 15\n");
  EXPECT_DOUBLE_EQ(open_source("euroc:" + d.str(), kDefaults)->camera()->fx, 45.8);
  SourceOptions o;
  o.camera_overridden = true;
  o.config_camera.fx = 123.0;
  EXPECT_DOUBLE_EQ(open_source("euroc:" + d.str(), o)->camera()->fx, 123.0);
}

TEST(DatasetEuroc, SharedMicroSequence) {
  const std::string dir = std::string(RDSLAM_SHARED_DIR) + "/data/euroc_V1_01_micro";
  if (!fs::exists(dir + "/mav0/cam0/data.csv")) {
    GTEST_SKIP() << "shared data not found at " << dir << " (../shared/data is absent)";
  }
  auto src = open_source(dir, kDefaults);  // auto-detected
  EXPECT_EQ(src->info().kind, "euroc");
  EXPECT_EQ(src->info().width, 752);
  EXPECT_EQ(src->info().height, 480);
  EXPECT_EQ(src->info().frame_count, 95);
  EXPECT_NEAR(src->info().nominal_fps, 20.0, 0.01);
  const CameraModel cam = *src->camera();
  EXPECT_DOUBLE_EQ(cam.fx, 458.654);  // SOURCE.md / sensor.yaml
  EXPECT_DOUBLE_EQ(cam.cy, 248.375);
  EXPECT_DOUBLE_EQ(cam.k1, -0.28340811);
  Frame f;
  int n = 0;
  int64_t first = 0, last = 0;
  while (src->read(f, 0) == SourceStatus::kOk) {
    if (n == 0) {
      first = f.stamp_ns;
      const cv::Mat ref =
          cv::imread(dir + "/mav0/cam0/data/1403715273262142976.png", cv::IMREAD_UNCHANGED);
      EXPECT_TRUE(same_pixels(f.image, ref));
    }
    last = f.stamp_ns;
    ++n;
  }
  EXPECT_EQ(n, 95);
  EXPECT_EQ(first, 1403715273262142976LL);
  EXPECT_EQ(last, 1403715277962142976LL);
  EXPECT_EQ(src->counters().faults, 0u);

  // Ground truth: every cam0 time has a row (SOURCE.md); the camera pose is the body pose
  // composed with T_BS, so the camera sits 6.7 cm from the body origin (|t_BS|).
  const Trajectory gt = *src->ground_truth();
  ASSERT_EQ(gt.size(), 2895u);
  const Trajectory body =
      read_trajectory(dir + "/mav0/state_groundtruth_estimate0/data.csv", TrajectoryFormat::kEuroc);
  ASSERT_EQ(body.size(), gt.size());
  EXPECT_EQ(gt[0].stamp_ns, first);
  EXPECT_NEAR((gt[0].p_world_cam - body[0].p_world_cam).norm(),
              Eigen::Vector3d(-0.0216401454975, -0.064676986768, 0.00981073058949).norm(), 1e-9);
  // The vehicle is at rest: the camera moves < 2 cm over the 95 frames.
  EXPECT_LT((gt[94].p_world_cam - gt[0].p_world_cam).norm(), 0.02);
}
