#include "firmware_app/lcm_publisher.h"

#include <lcm/lcm.h>

#include <stdexcept>

#include "bot_core/pose_t.hpp"
#include "core/log.h"
#include "rdslam/pose_t.hpp"
#include "rdslam/status_t.hpp"

namespace rdslam {

LcmPublisher::LcmPublisher(const LcmParams& params) : params_(params) {
  lcm_ = lcm_create(params_.url.c_str());
  if (!lcm_) throw std::runtime_error("lcm: cannot open provider URL '" + params_.url + "'");
}

LcmPublisher::~LcmPublisher() {
  if (lcm_) lcm_destroy(lcm_);
}

bool LcmPublisher::send(const std::string& channel, const void* data, int size) {
  if (size < 0 || lcm_publish(lcm_, channel.c_str(), data, static_cast<unsigned>(size)) != 0) {
    // Count, and warn only for the first few so a dead network cannot flood the journal.
    if (failures_.fetch_add(1, std::memory_order_relaxed) < 5) {
      RDSLAM_LOG_WARN("lcm: publishing on %s failed", channel.c_str());
    }
    return false;
  }
  return true;
}

void LcmPublisher::on_frame(const FrameResult& fr) {
  const TrackResult& r = fr.result;
  ::rdslam::pose_t m;  // fixed-size arrays only: lives on the stack
  m.version = ::rdslam::pose_t::VERSION;
  m.utime = fr.stamp_ns / 1000;
  m.seq = static_cast<int64_t>(fr.seq);
  m.map_epoch = static_cast<int64_t>(r.epoch);
  for (int i = 0; i < 3; ++i) m.position[i] = r.p_world_cam[i];
  m.orientation[0] = r.q_world_cam.w();
  m.orientation[1] = r.q_world_cam.x();
  m.orientation[2] = r.q_world_cam.y();
  m.orientation[3] = r.q_world_cam.z();
  for (int i = 0; i < 36; ++i) m.covariance[i] = r.covariance[i];
  m.quality = r.quality;
  m.inliers = r.inliers;
  m.state = static_cast<int8_t>(r.state);
  m.latency_us = fr.latency_ns() / 1000;
  const int n = m.encode(buf_, 0, sizeof(buf_));
  if (send(params_.pose_channel, buf_, n)) poses_.fetch_add(1, std::memory_order_relaxed);

  if (params_.publish_bot_core_pose) {
    ::bot_core::pose_t b;
    b.utime = m.utime;
    for (int i = 0; i < 3; ++i) {
      b.pos[i] = m.position[i];
      b.vel[i] = 0.0;  // not estimated
      b.rotation_rate[i] = 0.0;
      b.accel[i] = 0.0;
    }
    for (int i = 0; i < 4; ++i) b.orientation[i] = m.orientation[i];  // w, x, y, z as libbot2
    const int nb = b.encode(buf_, 0, sizeof(buf_));
    send(params_.bot_core_pose_channel, buf_, nb);
  }
}

void LcmPublisher::on_status(const PipelineStatus& s) {
  ::rdslam::status_t m;
  m.utime = s.mono_ns / 1000;
  m.state = static_cast<int8_t>(s.state);
  m.fps = s.fps;
  m.latency_p50_ms = s.latency_p50_ms;
  m.latency_p99_ms = s.latency_p99_ms;
  m.tracker_p50_ms = s.tracker_p50_ms;
  m.tracker_p99_ms = s.tracker_p99_ms;
  m.frames_captured = static_cast<int64_t>(s.frames_captured);
  m.frames_processed = static_cast<int64_t>(s.frames_processed);
  m.frames_dropped = static_cast<int64_t>(s.frames_dropped);
  m.source_faults = static_cast<int64_t>(s.source_faults);
  m.map_points = s.map_points;
  m.keyframes = s.keyframes;
  m.invalidated_points = s.invalidated_points;
  m.cpu_capture_s = s.cpu_s[kCaptureThread];
  m.cpu_tracker_s = s.cpu_s[kTrackerThread];
  m.cpu_mapper_s = s.cpu_s[kMapperThread];
  m.map_epoch = static_cast<int64_t>(s.map_epoch);
  m.source_timeouts = static_cast<int64_t>(s.source_timeouts);
  m.source_reopens = static_cast<int64_t>(s.source_reopens);
  m.frames_invalid = static_cast<int64_t>(s.frames_invalid);
  m.stamps_rejected = static_cast<int64_t>(s.stamps_rejected);
  m.frames_blank = static_cast<int64_t>(s.frames_blank);
  m.exposure_jumps = static_cast<int64_t>(s.exposure_jumps);
  const int n = m.encode(buf_, 0, sizeof(buf_));
  if (send(params_.status_channel, buf_, n)) statuses_.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace rdslam
