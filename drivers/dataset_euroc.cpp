#include "drivers/dataset_euroc.h"

#include <yaml-cpp/yaml.h>
#include <cmath>

#include <Eigen/SVD>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace rdslam {

namespace fs = std::filesystem;

namespace {

std::vector<double> numbers(const YAML::Node& n, const std::string& path, const char* key,
                            size_t count) {
  if (!n || !n.IsSequence() || n.size() != count) {
    throw std::runtime_error(path + ": " + key + ": expected a list of " + std::to_string(count) +
                             " numbers");
  }
  std::vector<double> out;
  for (const auto& e : n) {
    try {
      out.push_back(e.as<double>());
    } catch (const YAML::Exception&) {
      throw std::runtime_error(path + ": " + key + ": '" + (e.IsScalar() ? e.Scalar() : "?") +
                               "' is not a number");
    }
  }
  return out;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return {};
  const size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

}  // namespace

std::string euroc_mav0_dir(const std::string& dir) {
  const fs::path root(dir);
  if (fs::is_regular_file(root / "mav0" / "cam0" / "data.csv")) return (root / "mav0").string();
  if (fs::is_regular_file(root / "cam0" / "data.csv")) return root.string();
  return {};
}

bool looks_like_euroc(const std::string& dir) {
  return !euroc_mav0_dir(dir).empty();
}

EurocCameraInfo read_euroc_camera_yaml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open camera sensor.yaml");
  std::stringstream text;
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    // OpenCV FileStorage's "%YAML:1.0" directive is not YAML 1.2: drop it.
    if (first && line.rfind("%YAML", 0) == 0) line = "";
    first = false;
    text << line << '\n';
  }
  YAML::Node root;
  try {
    root = YAML::Load(text.str());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  EurocCameraInfo out;
  CameraModel& cam = out.camera;
  cam.k1 = cam.k2 = cam.p1 = cam.p2 = cam.k3 = cam.k4 = 0.0;
  const std::string model = root["camera_model"] ? root["camera_model"].as<std::string>() : "";
  if (model != "pinhole") {
    throw std::runtime_error(path + ": camera_model: '" + model +
                             "' is not supported; allowed pinhole");
  }
  const auto res = numbers(root["resolution"], path, "resolution", 2);
  // Checked before the conversion: a double outside int's range is undefined behaviour to cast.
  for (double v : res) {
    if (!(v >= 1.0 && v <= 65536.0) || v != std::floor(v)) {
      throw std::runtime_error(path + ": resolution: " + std::to_string(v) +
                               " is not a whole number of pixels in [1, 65536]");
    }
  }
  cam.width = static_cast<int>(res[0]);
  cam.height = static_cast<int>(res[1]);
  const auto k = numbers(root["intrinsics"], path, "intrinsics", 4);
  cam.fx = k[0];
  cam.fy = k[1];
  cam.cx = k[2];
  cam.cy = k[3];
  const std::string dist =
      root["distortion_model"] ? root["distortion_model"].as<std::string>() : "radial-tangential";
  const YAML::Node dn = root["distortion_coefficients"];
  if (dist == "radial-tangential" || dist == "radtan") {
    cam.model = "pinhole-radtan";
    const auto d = numbers(dn, path, "distortion_coefficients", dn && dn.size() == 5 ? 5 : 4);
    cam.k1 = d[0];
    cam.k2 = d[1];
    cam.p1 = d[2];
    cam.p2 = d[3];
    if (d.size() == 5) cam.k3 = d[4];
  } else if (dist == "equidistant") {
    cam.model = "pinhole-equidistant";
    const auto d = numbers(dn, path, "distortion_coefficients", 4);
    cam.k1 = d[0];
    cam.k2 = d[1];
    cam.k3 = d[2];
    cam.k4 = d[3];
  } else {
    throw std::runtime_error(path + ": distortion_model: '" + dist +
                             "' is not supported; allowed radial-tangential, equidistant");
  }
  const std::string err = cam.validate();
  if (!err.empty()) throw std::runtime_error(path + ": " + err);

  const YAML::Node tbs = root["T_BS"];
  if (!tbs) throw std::runtime_error(path + ": missing T_BS (camera extrinsic)");
  const auto t = numbers(tbs["data"], path, "T_BS.data", 16);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = t[static_cast<size_t>(r * 4 + c)];
  }
  // The calibration prints R with ~12 digits: re-orthonormalize, and reject anything that
  // is not a rigid transform.
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d Rn = svd.matrixU() * svd.matrixV().transpose();
  if (Rn.determinant() < 0 || (Rn - R).norm() > 1e-3 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    throw std::runtime_error(path + ": T_BS is not a rigid transform");
  }
  out.T_body_cam.linear() = Rn;
  out.T_body_cam.translation() = m.topRightCorner<3, 1>();
  if (root["rate_hz"]) out.rate_hz = root["rate_hz"].as<double>();
  return out;
}

Trajectory body_to_camera(const Trajectory& T_world_body, const Eigen::Isometry3d& T_body_cam) {
  Trajectory out;
  out.reserve(T_world_body.size());
  const Eigen::Quaterniond q_body_cam(T_body_cam.linear());
  for (const auto& p : T_world_body) {
    StampedPose c;
    c.stamp_ns = p.stamp_ns;
    // p_world_cam = R_world_body * p_body_cam + p_world_body.
    c.p_world_cam = p.q_world_cam * T_body_cam.translation() + p.p_world_cam;
    c.q_world_cam = (p.q_world_cam * q_body_cam).normalized();
    out.push_back(c);
  }
  return out;
}

std::unique_ptr<ReplaySource> open_euroc_source(const std::string& uri, const std::string& dir,
                                                double speed) {
  const std::string mav0 = euroc_mav0_dir(dir);
  if (mav0.empty()) {
    throw std::runtime_error(dir + ": not an EuRoC/ASL folder (no mav0/cam0/data.csv)");
  }
  const fs::path cam0 = fs::path(mav0) / "cam0";
  const std::string list = (cam0 / "data.csv").string();
  std::ifstream in(list);
  if (!in) throw std::runtime_error(list + ": cannot open");
  std::vector<ImageFileSequence::Item> items;
  std::string line;
  for (size_t n = 1; std::getline(in, line); ++n) {
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const size_t comma = t.find(',');
    if (comma == std::string::npos) {
      throw std::runtime_error(list + ":" + std::to_string(n) + ": expected 'timestamp,filename'");
    }
    const std::string stamp = trim(t.substr(0, comma));
    const std::string name = trim(t.substr(comma + 1));
    ImageFileSequence::Item item;
    const auto r = std::from_chars(stamp.data(), stamp.data() + stamp.size(), item.stamp_ns);
    if (stamp.empty() || r.ec != std::errc() || r.ptr != stamp.data() + stamp.size() ||
        name.empty()) {
      throw std::runtime_error(list + ":" + std::to_string(n) +
                               ": expected 'timestamp[ns],filename', found '" + t + "'");
    }
    item.path = (cam0 / "data" / name).string();
    items.push_back(std::move(item));
  }
  const EurocCameraInfo calib = read_euroc_camera_yaml((cam0 / "sensor.yaml").string());
  std::optional<Trajectory> gt;
  const fs::path gt_csv = fs::path(mav0) / "state_groundtruth_estimate0" / "data.csv";
  if (fs::is_regular_file(gt_csv)) {
    gt = body_to_camera(read_trajectory(gt_csv.string(), TrajectoryFormat::kEuroc),
                        calib.T_body_cam);
  }
  auto src = make_image_replay(uri, "euroc", std::move(items), calib.camera, std::move(gt), speed);
  if (src->info().width != calib.camera.width || src->info().height != calib.camera.height) {
    throw std::runtime_error(
        cam0.string() + ": images are " + std::to_string(src->info().width) + "x" +
        std::to_string(src->info().height) + " but sensor.yaml says resolution " +
        std::to_string(calib.camera.width) + "x" + std::to_string(calib.camera.height));
  }
  return src;
}

}  // namespace rdslam
