// Synthetic dynamic scene: a room of photo-textured planar quads, objects with their own
// motion, a hand-held camera trajectory, lights and exposure, all as exact functions of the
// frame index. It is the ground truth behind `synth:SCENARIO` (issue 5): camera poses, which
// object each surface belongs to, and when each object moves, appears or disappears.
//
// Coordinate frames (docs/synthetic.md):
//   world: metres, z up, floor at z = 0; the room spans x in [-W/2, W/2], y in [-D/2, D/2],
//          z in [0, H]; the "north" wall (y = +D/2) is the one most scenarios look at.
//   camera: OpenCV convention, x right, y down, z forward (optical axis).
//   poses: T_world_cam maps camera coordinates to world (p_world = T_world_cam * p_cam);
//          T_world_obj likewise for objects.
// Object id 0 means "nothing"; id 1 is the room (walls, floor, ceiling); objects follow in
// file order from 2.
//
// Ownership: a SynthScene is an immutable value once built (load_synth_scene). Threads: any
// thread may call its const queries concurrently.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <climits>
#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"

namespace rdslam {

using SynthPoseVector = std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>;

// A planar rectangle in its object's frame: X(s, t) = p0 + s*u + t*v with s, t in [0, 1].
// Laid out like an image seen from its visible side: u points right, v points down, so the
// visible side's normal is v x u. Texture coordinates (in repeats of the texture) are
// uv0 + (s, t) .* uv_scale.
struct SynthQuad {
  Eigen::Vector3d p0{0, 0, 0};
  Eigen::Vector3d u{1, 0, 0};
  Eigen::Vector3d v{0, 1, 0};
  int texture = 0;  // index into SynthScene::textures
  Eigen::Vector2d uv0{0, 0};
  Eigen::Vector2d uv_scale{1, 1};
  double albedo = 1.0;  // brightness multiplier of the texture
  bool two_sided = false;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// A texture: a photograph from data/textures/ (or any path), optionally with reduced contrast
// and blur so a scenario can make a background poorer in features than a moving object.
struct SynthTextureSpec {
  std::string path;       // resolved file path
  double contrast = 1.0;  // 1 = as photographed; < 1 pulls pixels towards the mean
  double blur_px = 0.0;   // Gaussian sigma in texels, 0 = none
};

// Object motion: moves are applied in order (stay, then move to `to` during [start, end],
// then stay); a wobble adds a periodic 6-DoF offset in the object frame during its range
// (hand-held book, a seated person's sway, a walker's bounce), faded in and out.
struct SynthMove {
  int start = 0;
  int end = 0;
  Eigen::Isometry3d to = Eigen::Isometry3d::Identity();
  bool linear = false;  // false: smoothstep ease in/out; true: constant speed (walking)
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct SynthWobble {
  Eigen::Vector3d amplitude_m{0, 0, 0};
  Eigen::Vector3d amplitude_rad{0, 0, 0};  // roll pitch yaw about the object's x y z
  double period_s = 2.0;
  int start = 0;
  int end = INT_MAX;
  double fade_s = 0.5;
  bool enabled = false;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct SynthObject {
  std::string name;
  int id = 0;
  std::vector<SynthQuad, Eigen::aligned_allocator<SynthQuad>> quads;  // in the object frame
  Eigen::Isometry3d pose0 = Eigen::Isometry3d::Identity();            // T_world_obj at frame 0
  std::vector<SynthMove, Eigen::aligned_allocator<SynthMove>> moves;
  SynthWobble wobble;
  // Label of the motion variant the seed chose (key `variants`), empty when there is none.
  std::string variant;
  int visible_from = 0;  // visible for frames in [visible_from, visible_until)
  int visible_until = INT_MAX;
  // Derived from the motion by the loader (exact, frame by frame):
  int first_change = INT_MAX;   // first frame whose pose differs from frame 0, or appearance
  SynthPoseVector poses;        // T_world_obj per frame
  std::vector<uint8_t> moving;  // per frame: pose differs from the previous frame
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// What a scene change is, for events.yaml and tests.
struct SynthEvent {
  int object_id = 0;  // 0 for scene-wide events (light, exposure)
  std::string object_name;
  std::string kind;  // move | appear | disappear | light | exposure
  int first_frame = 0;
  int last_frame = 0;  // inclusive
};

struct SynthSpotLight {
  bool enabled = false;
  Eigen::Vector3d position{0, -1.5, 1.6};  // world; a flashlight held near the camera
  Eigen::Vector3d target{0, 2.5, 1.0};     // centre of the sweep
  Eigen::Vector3d sweep_m{1.5, 0.0, 0.6};  // sweep amplitude of the aim point
  double period_s = 6.0;
  double cone_deg = 12.0;  // half-angle of the bright core
  double edge_deg = 6.0;   // soft edge width beyond the core
  double intensity = 4.0;  // added gain at 1 m on a surface facing the light
  int start = 0;
  int end = INT_MAX;
};

struct SynthRenderOptions {
  double noise_sigma = 2.0;     // Gaussian sensor noise, grey levels (8-bit)
  int motion_blur_samples = 0;  // 0 = off; N > 1 averages N sub-frames over the shutter
  double shutter = 0.5;         // exposure time as a fraction of the frame period
  double near_m = 0.05;         // near clipping plane
  double ambient = 0.6;         // shading: ambient + diffuse * max(0, n . sun)
  double diffuse = 0.4;
  // Mip levels down to one texel (long scenes: a distant surface fades to its mean colour);
  // false keeps the original chain, which stops at about 4 texels.
  bool full_mip_chain = false;
};

struct SynthTrajectorySpec {
  std::string type = "xyz";              // xyz | halfsphere | rpy | static | forward | path | turn
  Eigen::Vector3d center{0, -1.3, 1.3};  // xyz/rpy/static: mean camera centre; forward: start
  Eigen::Vector3d target{0, 2.5, 1.0};   // the point the camera looks at (forward: sets the
                                         // direction of travel, target - center)
  // xyz: translation amplitudes per world axis; forward: offsets along the path's
  // (right, forward, up) axes (the forward one varies the speed).
  Eigen::Vector3d amplitude_m{0.35, 0.15, 0.15};
  Eigen::Vector3d period_s{6.0, 7.7, 4.9};  // xyz, forward: periods of those sinusoids
  double speed_m_s = 10.0;                  // forward: mean speed along the direction of travel
  double radius_m = 2.2;                    // halfsphere: distance to target
  double azimuth_deg = 35.0;                // halfsphere: +- sweep about the -y direction
  double elevation_deg = 20.0;              // halfsphere: mean elevation
  double elevation_amp_deg = 10.0;
  double azimuth_period_s = 10.0;
  double elevation_period_s = 7.0;
  Eigen::Vector3d rpy_amp_deg{10, 10, 15};  // rpy, forward: roll pitch yaw amplitudes
  double shake = 1.0;                       // hand-held jitter scale (0 = tripod)
  std::vector<std::pair<int, int>> pauses;  // [first, last) frames where the camera stands still
  // path: camera centre keys (frame, position), linear between them (held before the first and
  // after the last), plus the xyz sinusoids (amplitude_m, default 0); looks at `target`, or at
  // per-key look-at points (path_target, same length, interpolated alike) when the keys have them.
  std::vector<std::pair<double, Eigen::Vector3d>> path;
  std::vector<Eigen::Vector3d> path_target;
  // turn (a differential-drive robot): from `center`, heading to `target` (horizontally),
  // drive drive_m[0] metres, turn turn_deg on the spot (positive: to the left, about world
  // +z), then drive drive_m[1] metres along the new heading. Each leg eases in and out
  // (smoothstep: the mean speed is speed_m_s, resp. turn_rate_deg_s; the peak 1.5 times it).
  // The camera sits axis_offset_m ahead of the rotation axis (0: on the axis, pure rotation).
  Eigen::Vector2d drive_m{1.0, 1.5};
  double turn_deg = 360.0;
  double turn_rate_deg_s = 40.0;
  double axis_offset_m = 0.0;
};

// Result of a surface query: which object's quad a world point lies on.
struct SynthSurfaceHit {
  int object_id = 0;               // 0: the point lies on no surface (within tolerance)
  int quad = -1;                   // index into the object's quads
  Eigen::Vector3d p_obj{0, 0, 0};  // the point in the object frame
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// Fate of a world point seen at frame_ref when looked at again at frame k (for the dynamic
// environment tests: "did the surface it lay on move, or was it only occluded?").
struct SynthPointFate {
  int object_id = 0;                     // surface the point lay on at frame_ref (0: none)
  bool moved = false;                    // its surface moved or vanished between frame_ref and k
  bool occluded = false;                 // at k, something else is in front of where the point was
  bool in_view = false;                  // at k, the point (where it was) projects inside the image
  int occluder_id = 0;                   // id of the occluding surface when occluded
  Eigen::Vector3d p_world_now{0, 0, 0};  // where the surface point is at frame k
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct SynthScene {
  std::string name;
  int frame_count = 300;
  double fps = 30.0;
  uint64_t seed = 1;
  CameraModel camera;
  SynthRenderOptions render;
  SynthTrajectorySpec trajectory;
  SynthSpotLight light;
  std::vector<std::pair<int, double>> exposure_keys;  // (frame, gain), piecewise linear
  std::vector<SynthTextureSpec> textures;
  std::vector<SynthObject, Eigen::aligned_allocator<SynthObject>> objects;  // objects[i].id = i+1
  // Per-frame ground truth, derived by the loader.
  SynthPoseVector T_world_cam;
  std::vector<double> exposure;
  std::vector<SynthEvent> events;

  // Camera pose at a (possibly fractional) frame; exact, used for motion blur.
  Eigen::Isometry3d camera_pose(double frame) const;
  // T_world_obj at a (possibly fractional) frame.
  Eigen::Isometry3d object_pose(int id, double frame) const;
  const SynthObject* object(int id) const;
  const SynthObject* object(const std::string& name) const;
  bool object_visible(int id, int frame) const;
  // True when the object moves at `frame` or has moved (or appeared) since frame 0: the
  // definition of the dynamic mask.
  bool object_dynamic(int id, int frame) const;
  // True when the object's pose or visibility differs between the two frames.
  bool moved_between(int id, int frame_a, int frame_b) const;
  // Spot light state at a frame: aim direction in world and whether it is on.
  bool light_on(int frame) const;
  Eigen::Vector3d light_aim(double frame) const;

  // The surface a world point lies on at `frame` (distance to the plane <= tol_m, inside the
  // quad). Nearest plane wins.
  SynthSurfaceHit surface_at(const Eigen::Vector3d& p_world, int frame, double tol_m = 0.01) const;
  // First surface hit by the ray origin + lambda * dir (lambda > 0) at `frame`; returns the
  // object id (0: none) and the distance along dir (dir need not be unit: lambda units).
  int raycast(int frame, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
              double* lambda_out) const;
  SynthPointFate point_fate(const Eigen::Vector3d& p_world, int frame_ref, int frame,
                            double tol_m = 0.01) const;
};

// Build a scene from a built-in scenario name (synth_scenario_names()) or a YAML file path.
// frames_override > 0 replaces the scenario's frame count; seed_override >= 0 its seed.
// Throws std::runtime_error naming the scenario/file and key on bad input (start-up boundary).
SynthScene load_synth_scene(const std::string& scenario_or_yaml, int frames_override = -1,
                            int64_t seed_override = -1);
// Same, from YAML text (`origin` names it in error messages).
SynthScene load_synth_scene_yaml(const std::string& yaml_text, const std::string& origin,
                                 int frames_override = -1, int64_t seed_override = -1);

// Built-in scenarios (drivers/synth_scenarios.cpp) and their YAML text.
const std::vector<std::string>& synth_scenario_names();
// Empty string when `name` is not a built-in scenario.
std::string synth_scenario_yaml(const std::string& name);
// Directory of the photographs (data/textures in the source tree, or $RDSLAM_TEXTURE_DIR).
std::string synth_texture_dir();

}  // namespace rdslam
