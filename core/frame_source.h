// The one interface through which every frame enters rdslam.
//
// A FrameSource fills a caller-owned, preallocated Frame. It never allocates per frame once
// the caller's buffer has the right size, never throws from read(), and reports end of
// stream, timeouts and faults as a SourceStatus. Construction (open_source) may throw
// std::runtime_error with a clear message: that is the start-up boundary.
//
// Ownership: the source owns its device/file handles. Threads: one thread (the capture
// thread) calls read(); info()/camera()/ground_truth() are immutable after open.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/trajectory.h"

namespace rdslam {

enum class PixelFormat : uint8_t { kGray8 = 0, kBgr8 = 1 };

struct Frame {
  cv::Mat image;  // preallocated by the owner; CV_8UC1 (kGray8) or CV_8UC3 (kBgr8)
  PixelFormat format = PixelFormat::kGray8;
  int64_t stamp_ns = 0;         // capture time of the image (sensor/dataset clock), ns
  int64_t arrival_mono_ns = 0;  // CLOCK_MONOTONIC when the frame entered rdslam (latency)
  uint64_t seq = 0;             // source sequence number, 0-based, never repeats
  int64_t dataset_index = -1;   // index in a recorded sequence, -1 for live cameras
};

enum class SourceStatus : uint8_t {
  kOk = 0,           // frame filled
  kEndOfStream = 1,  // recorded source exhausted; further reads keep returning this
  kTimeout = 2,      // nothing arrived within the timeout; try again
  kFault = 3,        // transient fault (corrupt frame, device reset); counted, try again
};

const char* to_string(SourceStatus s);

// CLOCK_MONOTONIC in nanoseconds: the clock of Frame::arrival_mono_ns and of every latency,
// deadline and watchdog figure in rdslam. Any thread.
int64_t mono_now_ns();

struct SourceInfo {
  std::string uri;   // as opened, e.g. "tum:/data/seq"
  std::string kind;  // "tum", "euroc", "kitti", "images", "video", "v4l2", "synth", ...
  int width = 0;
  int height = 0;
  PixelFormat format = PixelFormat::kGray8;
  double nominal_fps = 0.0;  // 0 if unknown
  bool live = false;         // true for cameras: frames arrive in real time
  int64_t frame_count = -1;  // recorded sources: number of frames; -1 if unknown/live
};

struct SourceCounters {
  uint64_t delivered = 0;
  uint64_t faults = 0;   // corrupt/undecodable frames skipped
  uint64_t reopens = 0;  // device reopen attempts after unplug
  uint64_t timeouts = 0;
  // Frames that were due but never delivered because the reader came late (paced replay,
  // LCM): the newest due frame wins, as with a live camera whose driver overwrites.
  uint64_t skipped = 0;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Fill `out` with the next frame. `out.image` is reused when it already has the right
  // size and type. Blocks at most `timeout_ms` for live sources.
  virtual SourceStatus read(Frame& out, int timeout_ms) = 0;
  virtual const SourceInfo& info() const = 0;
  // Intrinsics when the source knows them (dataset calibration, camera.yaml); otherwise
  // std::nullopt and the configuration's camera section applies.
  virtual std::optional<CameraModel> camera() const { return std::nullopt; }
  // Ground truth T_world_cam for recorded sequences that have it.
  virtual std::optional<Trajectory> ground_truth() const { return std::nullopt; }
  virtual SourceCounters counters() const { return {}; }
};

}  // namespace rdslam
