// libFuzzer target: the dataset index and calibration files the recorded sources read at
// start-up (drivers/dataset_tum.h, dataset_euroc.h, dataset_kitti.h, replay_source.h).
// Input: one byte choosing the file, then its content:
//   0 TUM rgb.txt   1 EuRoC mav0/cam0/data.csv   2 KITTI calib.txt   3 KITTI times.txt
//   4 EuRoC sensor.yaml   5 camera.yaml
// A bad file must end in std::runtime_error naming file and line (yaml-cpp's exceptions are
// std::runtime_errors too); anything else is a bug.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>

#include "drivers/dataset_euroc.h"
#include "drivers/dataset_kitti.h"
#include "drivers/dataset_tum.h"
#include "drivers/replay_source.h"
#include "tests/fuzz/fuzz_util.h"

namespace {

// A complete EuRoC camera folder but for data.csv: a valid sensor.yaml and one 8x6 image
// data/a.png (so that a well-formed list gets as far as opening the source).
const char kSensorYaml[] =
    "sensor_type: camera\n"
    "T_BS:\n  cols: 4\n  rows: 4\n"
    "  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]\n"
    "rate_hz: 20\nresolution: [8, 6]\ncamera_model: pinhole\n"
    "intrinsics: [4.0, 4.0, 3.5, 2.5]\ndistortion_model: radial-tangential\n"
    "distortion_coefficients: [0.0, 0.0, 0.0, 0.0]\n";
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  namespace f = rdslam::fuzz;
  const auto& dir = f::scratch_dir();
  const uint8_t* body = data + 1;
  const size_t n = size - 1;
  try {
    switch (data[0] % 6) {
      case 0:
        f::write_file(dir / "tum" / "rgb.txt", body, n);
        (void)rdslam::read_tum_dataset((dir / "tum").string());
        break;
      case 1: {
        static const bool ready = [&dir] {
          f::write_file(dir / "euroc" / "mav0" / "cam0" / "sensor.yaml", kSensorYaml);
          std::filesystem::create_directories(dir / "euroc" / "mav0" / "cam0" / "data");
          cv::imwrite((dir / "euroc" / "mav0" / "cam0" / "data" / "a.png").string(),
                      cv::Mat(6, 8, CV_8UC1, cv::Scalar(90)));
          return true;
        }();
        (void)ready;
        f::write_file(dir / "euroc" / "mav0" / "cam0" / "data.csv", body, n);
        const std::string d = (dir / "euroc").string();
        (void)rdslam::open_euroc_source("euroc:" + d, d, 0.0);
        break;
      }
      case 2:
        f::write_file(dir / "calib.txt", body, n);
        (void)rdslam::read_kitti_calib((dir / "calib.txt").string(), 1241, 376);
        break;
      case 3:
        f::write_file(dir / "times.txt", body, n);
        (void)rdslam::read_kitti_times((dir / "times.txt").string());
        break;
      case 4:
        f::write_file(dir / "sensor.yaml", body, n);
        (void)rdslam::read_euroc_camera_yaml((dir / "sensor.yaml").string());
        break;
      default:
        f::write_file(dir / "camera.yaml", body, n);
        (void)rdslam::read_camera_yaml((dir / "camera.yaml").string());
        break;
    }
  } catch (const std::runtime_error&) {
  }
  return 0;
}
