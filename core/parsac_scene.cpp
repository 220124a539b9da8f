#include "core/parsac_scene.h"

#include <cmath>
#include <random>

namespace rdslam {

namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d ypr(double yaw, double pitch, double roll) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

// Camera: a slow loop with a few degrees of yaw and pitch (world = first camera frame).
Eigen::Isometry3d camera_world_cam(int t, int frames) {
  const double s = 2.0 * M_PI * t / frames;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ypr(4.0 * kDeg * std::sin(s), 2.0 * kDeg * std::sin(2.0 * s), 0.0);
  T.translation() = Eigen::Vector3d(0.4 * std::sin(s), 0.1 * std::sin(2.0 * s), 0.3 * t / frames);
  return T;
}

// Object: translates and turns on its own schedule, always >= 10 degrees and ~0.5 m away from
// the pose it had when the map saw it, so its motion never looks like the camera's.
Eigen::Isometry3d object_world_obj(int t, int frames) {
  const double s = 2.0 * M_PI * t / frames;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ypr((20.0 + 10.0 * std::sin(1.7 * s)) * kDeg, 5.0 * kDeg * std::cos(s), 0.0);
  T.translation() = Eigen::Vector3d(0.1 + 0.35 * std::sin(1.3 * s), 0.1 * std::cos(s), 3.3);
  return T;
}

Eigen::Isometry3d object_world_obj_mapped() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(-0.5, 0.3, 3.8);
  return T;
}

}  // namespace

CameraModel parsac_scene_camera() {
  CameraModel cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = cam.fy = 525.0;
  cam.cx = 319.5;
  cam.cy = 239.5;
  return cam;
}

std::vector<ParsacFrame> make_parsac_scene(const ParsacSceneParams& p) {
  const CameraModel cam = parsac_scene_camera();
  std::mt19937_64 rng(p.seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  auto in_image = [&](const Eigen::Vector2d& x) {
    return x.x() >= 0 && x.x() < cam.width && x.y() >= 0 && x.y() < cam.height;
  };
  auto project = [&](const Eigen::Isometry3d& T_cw, const Eigen::Vector3d& X, Eigen::Vector2d* x) {
    const Eigen::Vector3d c = T_cw * X;
    if (c.z() <= 0.1) return false;
    *x = Eigen::Vector2d(cam.fx * c.x() / c.z() + cam.cx, cam.fy * c.y() / c.z() + cam.cy);
    return true;
  };
  auto backproject = [&](const Eigen::Isometry3d& T_wc, double u, double v, double depth) {
    const Eigen::Vector3d c((u - cam.cx) / cam.fx * depth, (v - cam.cy) / cam.fy * depth, depth);
    return Eigen::Vector3d(T_wc * c);
  };

  // Static background: uniform over the image of the first camera, depth 4..8 m.
  std::vector<Eigen::Vector3d> stat(p.static_points);
  const Eigen::Isometry3d T_wc0 = camera_world_cam(0, p.frames);
  for (auto& X : stat) {
    X = backproject(T_wc0, U(rng) * cam.width, U(rng) * cam.height, 4.0 + 4.0 * U(rng));
  }
  // Object: a 1.8 x 1.5 x 0.4 m box of points.
  std::vector<Eigen::Vector3d> obj(p.object_points);
  for (auto& X : obj)
    X = Eigen::Vector3d(1.8 * (U(rng) - 0.5), 1.5 * (U(rng) - 0.5), 0.4 * (U(rng) - 0.5));
  const Eigen::Isometry3d T_wo_map = object_world_obj_mapped();
  // Random movers: image trajectories with their own velocities (or blobs of them), each
  // matched to an unrelated map point.
  const int nc = std::max(0, p.random_clusters);
  std::vector<Eigen::Vector2d> centre(nc), centre_vel(nc);
  for (int c = 0; c < nc; ++c) {
    centre[c] = Eigen::Vector2d(U(rng) * cam.width, U(rng) * cam.height);
    centre_vel[c] = Eigen::Vector2d(6.0 * (U(rng) - 0.5), 6.0 * (U(rng) - 0.5));
  }
  std::vector<Eigen::Vector2d> rpos(p.random_points), rvel(p.random_points);
  std::vector<int> rcluster(p.random_points, -1);
  std::vector<Eigen::Vector3d> rmap(p.random_points);
  for (int i = 0; i < p.random_points; ++i) {
    if (nc > 0) {
      rcluster[i] = static_cast<int>(U(rng) * nc) % nc;
      rpos[i] = Eigen::Vector2d(N(rng), N(rng)) * p.cluster_sigma_px;  // offset from the centre
    } else {
      rpos[i] = Eigen::Vector2d(U(rng) * cam.width, U(rng) * cam.height);
    }
    rvel[i] = Eigen::Vector2d(6.0 * (U(rng) - 0.5), 6.0 * (U(rng) - 0.5));
    rmap[i] = backproject(T_wc0, U(rng) * cam.width, U(rng) * cam.height, 3.0 + 5.0 * U(rng));
  }
  auto bounce = [&](Eigen::Vector2d* x, Eigen::Vector2d* v) {
    for (int a = 0; a < 2; ++a) {
      const double lim = a == 0 ? cam.width - 1.0 : cam.height - 1.0;
      if ((*x)(a) < 0) {
        (*x)(a) = -(*x)(a);
        (*v)(a) = std::abs((*v)(a));
      } else if ((*x)(a) > lim) {
        (*x)(a) = 2 * lim - (*x)(a);
        (*v)(a) = -std::abs((*v)(a));
      }
    }
  };

  std::vector<ParsacFrame> frames(p.frames);
  for (int t = 0; t < p.frames; ++t) {
    ParsacFrame& f = frames[t];
    const Eigen::Isometry3d T_wc = camera_world_cam(t, p.frames);
    f.T_cam_world = T_wc.inverse();
    const Eigen::Isometry3d T_wo = object_world_obj(t, p.frames);
    f.T_object = f.T_cam_world * T_wo * T_wo_map.inverse();
    double depth_sum = 0.0;
    Eigen::Vector2d x;
    for (auto& X : stat) {
      if (!project(f.T_cam_world, X, &x) || !in_image(x)) {
        X = backproject(T_wc, U(rng) * cam.width, U(rng) * cam.height, 4.0 + 4.0 * U(rng));
        project(f.T_cam_world, X, &x);
      }
      depth_sum += (f.T_cam_world * X).z();
      f.pixels.push_back(x + p.noise_px * Eigen::Vector2d(N(rng), N(rng)));
      f.p_world.push_back(X);
      f.label.push_back(0);
    }
    f.mean_static_depth_m = stat.empty() ? 1.0 : depth_sum / stat.size();
    for (const auto& Xo : obj) {
      if (!project(f.T_cam_world, T_wo * Xo, &x) || !in_image(x)) continue;
      f.pixels.push_back(x + p.noise_px * Eigen::Vector2d(N(rng), N(rng)));
      f.p_world.push_back(T_wo_map * Xo);
      f.label.push_back(1);
    }
    for (int c = 0; c < nc; ++c) {
      centre[c] += centre_vel[c];
      bounce(&centre[c], &centre_vel[c]);
    }
    for (int i = 0; i < p.random_points; ++i) {
      if (nc > 0) {
        rpos[i] += 0.3 * rvel[i] / 3.0;  // jitter inside the blob
        x = centre[rcluster[i]] + rpos[i];
        x.x() = std::min(cam.width - 1.0, std::max(0.0, x.x()));
        x.y() = std::min(cam.height - 1.0, std::max(0.0, x.y()));
      } else {
        rpos[i] += rvel[i];
        bounce(&rpos[i], &rvel[i]);
        x = rpos[i];
      }
      f.pixels.push_back(x + p.noise_px * Eigen::Vector2d(N(rng), N(rng)));
      f.p_world.push_back(rmap[i]);
      f.label.push_back(2);
    }
  }
  return frames;
}

bool pose_matches(const Eigen::Isometry3d& T_est, const Eigen::Isometry3d& T_true,
                  double mean_depth_m, double max_rot_deg, double max_centre_frac) {
  const Eigen::AngleAxisd dR(T_est.linear() * T_true.linear().transpose());
  const double rot_deg = std::abs(dR.angle()) * 180.0 / M_PI;
  const Eigen::Vector3d c_est = -T_est.linear().transpose() * T_est.translation();
  const Eigen::Vector3d c_true = -T_true.linear().transpose() * T_true.translation();
  return rot_deg < max_rot_deg && (c_est - c_true).norm() < max_centre_frac * mean_depth_m;
}

}  // namespace rdslam
