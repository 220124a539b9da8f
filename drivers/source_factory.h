// Opening frame sources by URI: `v4l2:/dev/video0`, `libcamera:0`, `tum:DIR`, `euroc:DIR`,
// `kitti:DIR`, `images:DIR`, `video:FILE`, `synth:SCENARIO`, `lcm:CHANNEL`; a bare path is
// auto-detected from its content.
//
// Threads: call from the start-up thread. Throws std::runtime_error naming the URI and the
// reason when a source cannot be opened (start-up boundary).
#pragma once

#include <memory>
#include <string>

#include "core/frame_source.h"
#include "drivers/libcamera_source.h"
#include "drivers/v4l2_source.h"

namespace rdslam {

struct SourceOptions {
  // Replay pacing for recorded sources: 0 = as fast as the consumer reads; X > 0 = real
  // time at the recorded timestamps scaled by X (hardware-in-the-loop).
  double speed = 0.0;
  // Camera from the configuration: used when the source has no calibration of its own.
  CameraModel config_camera;
  // True when the user overrode camera.* explicitly (--set camera.*): wins over the dataset.
  bool camera_overridden = false;
  // For KITTI without times.txt: frame rate in Hz.
  double kitti_rate_hz = 10.0;
  // lcm: source URL (ttl=0 keeps traffic on this host).
  std::string lcm_url = "udpm://239.255.76.67:7667?ttl=0";
  // Live cameras: the config's v4l2 / libcamera sections (copy AppConfig::v4l2/libcamera).
  V4l2Params v4l2;
  LibcameraParams libcamera;
};

std::unique_ptr<FrameSource> open_source(const std::string& uri, const SourceOptions& options);

}  // namespace rdslam
