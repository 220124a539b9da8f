// rdslam's configuration: one YAML file (systemd/rdslam.yaml is the documented default)
// plus `--set key=value` overrides with the YAML's dotted keys.
//
// Every section is a plain parameter struct with the paper's defaults and a visit() that
// names its keys and ranges (core/params.h). The loader rejects unknown keys, wrong types
// and out-of-range values with a ConfigError naming the key, the value and what is allowed.
//
// Ownership: AppConfig is a value; load_config() returns a fresh one. Threads: start-up only.
#pragma once

#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/params.h"
#include "core/parsac.h"
#include "core/slam.h"
#include "drivers/libcamera_source.h"
#include "drivers/v4l2_source.h"
#include "firmware_app/map_files.h"
#include "firmware_app/pipeline_params.h"

namespace rdslam {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LcmParams {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  std::string pose_channel = "RDSLAM_POSE";
  std::string status_channel = "RDSLAM_STATUS";
  bool publish_bot_core_pose = false;
  std::string bot_core_pose_channel = "POSE_BODY";
  std::string image_channel = "RDSLAM_IMAGE";  // bot_core.image_t JPEG for viewers
  std::string map_channel = "RDSLAM_MAP";      // rdslam.map_t for viewers
  // rdslam.command_t that `rdslam run` obeys (firmware_app/lcm_commands.h); "" = none
  std::string command_channel = "RDSLAM_COMMAND";
  void visit(ParamVisitor& v);
};

// What `rdslam run` and `rdslam replay --lcm` publish for viewers (rdslam view;
// firmware_app/viewer_publisher.h): an annotated camera image and a map sample, at low rates,
// off the capture-to-publish path. Both rates 0: nothing (the tracker emits no debug record).
struct ViewerParams {
  double image_hz = 2.0;      // annotated JPEG images per second (0 = none)
  double map_hz = 1.0;        // rdslam.map_t per second (0 = none)
  int map_max_points = 5000;  // points per rdslam.map_t at most (a strided sample)
  int image_max_width = 640;  // larger images are downscaled to this width
  int jpeg_quality = 70;
  bool enabled() const { return image_hz > 0.0 || map_hz > 0.0; }
  void visit(ParamVisitor& v);
};

struct GeneralParams {
  std::string source = "synth:static_xyz";  // frame source URI (drivers/source_factory.h)
  std::string log_level = "info";
  void visit(ParamVisitor& v);
};

struct AppConfig {
  GeneralParams general;  // top-level keys: source, log_level
  CameraModel camera;
  LcmParams lcm;
  ViewerParams viewer;        // image and map for viewers (firmware_app/viewer_publisher.h)
  V4l2Params v4l2;            // USB cameras (drivers/v4l2_source.h)
  LibcameraParams libcamera;  // CSI cameras through libcamera (drivers/libcamera_source.h)
  PipelineParams pipeline;    // frame pool, rings, replay pacing (firmware_app/pipeline.h)
  ThreadParams threads;       // cores and priority per pipeline thread
  SlamParams slam;            // features, tracker, mapper sections (core/slam.h)
  ParsacParams parsac;        // robust pose estimation, RDSLAM Sec. 5 (core/parsac.h)
  MapFileParams map;          // saving the map in `rdslam run` (firmware_app/map_files.h)

  // Sections in file order: {yaml key, visitor}. An empty key means top-level fields.
  // A module adds its parameter struct as a member above and one line in sections().
  struct Section {
    const char* key;
    std::function<void(ParamVisitor&)> visit;
  };
  std::vector<Section> sections();
  // Cross-field checks after loading; throws ConfigError.
  void validate() const;
};

// Load `path` (empty: defaults only) and apply overrides "dotted.key=value" in order.
// Throws ConfigError.
AppConfig load_config(const std::string& path, const std::vector<std::string>& overrides);

// Effective configuration as YAML text (what ran), and the dotted keys whose values differ
// from the defaults as "key=value" strings (logged at start-up).
std::string dump_config(AppConfig& config);
std::vector<std::string> non_default_params(AppConfig& config);

// True when `overrides` set any camera.* key (the user's camera wins over the dataset's).
bool overrides_camera(const std::vector<std::string>& overrides);

}  // namespace rdslam
