// V4L2 USB (UVC) camera source: `v4l2:/dev/video0` (or a stable /dev/v4l/by-id/... path).
//
// Start-up: open, VIDIOC_QUERYCAP, format negotiation (MJPEG preferred, YUYV fallback, GREY
// last; or forced by v4l2.pixel_format), size (VIDIOC_S_FMT), frame rate (VIDIOC_S_PARM),
// exposure/gain/white-balance controls, mmap streaming with v4l2.buffers buffers.
// Per frame: poll with the caller's timeout, VIDIOC_DQBUF, MJPEG decode (TurboJPEG) or YUYV
// conversion straight into the caller's preallocated Frame, VIDIOC_QBUF. No heap allocation
// after the first read() sized the caller's buffer.
//
// Timestamps: the kernel's buffer timestamp (CLOCK_MONOTONIC) is the time the driver
// RECEIVED the frame (uvcvideo: first USB packet of the frame, V4L2_BUF_FLAG_TSTAMP_SRC_SOE),
// not the middle of the exposure; v4l2.stamp_offset_ms is subtracted to correct for exposure
// + readout + transfer when it is known for a camera (docs/cameras.md). Drivers without
// monotonic timestamps fall back to the DQBUF time.
//
// Faults never throw from read(): a corrupt MJPEG/short YUYV frame or a buffer flagged
// V4L2_BUF_FLAG_ERROR is requeued, counted and reported as kFault; ENODEV/EIO (unplug) closes
// the device and read() keeps trying to reopen it with exponential backoff while returning
// kTimeout, so the pipeline keeps running and resumes when the camera comes back.
//
// Ownership: the source owns the device descriptor and the mmap'ed buffers. Threads: the
// capture thread calls read(); counters()/stats() may be read from any thread (atomics);
// info() is immutable after construction.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/frame_source.h"
#include "core/params.h"

namespace rdslam {

class V4l2Syscalls;

// Config section `v4l2` (systemd/rdslam.yaml).
struct V4l2Params {
  std::string pixel_format = "auto";  // auto | mjpeg | yuyv | grey
  std::string output = "grey";        // grey | bgr: what read() delivers
  int width = 0;                      // 0: camera.width
  int height = 0;                     // 0: camera.height
  double fps = 30.0;                  // requested with VIDIOC_S_PARM
  int buffers = 4;                    // mmap buffers (kernel queue depth)
  int exposure_us = -1;               // -1 leave as is, 0 auto, > 0 manual exposure in us
  int gain = -1;                      // -1 leave as is, >= 0 manual gain (driver units)
  int white_balance_k = -1;           // -1 leave as is, 0 auto, > 0 manual temperature in K
  double stamp_offset_ms = 0.0;       // subtracted from the kernel timestamp (see above)
  bool newest_only = true;            // drain the kernel queue and deliver the newest frame
  bool mjpeg_strict = true;           // reject MJPEG frames libjpeg only warns about
  int reopen_backoff_ms = 100;        // first reopen delay after an unplug
  int reopen_backoff_max_ms = 2000;   // backoff doubles up to this

  void visit(ParamVisitor& v);
  // Cross-field checks; empty when valid, else a message naming the key.
  std::string validate() const;
};

// Diagnostics beyond SourceCounters.
struct V4l2Stats {
  uint64_t corrupt = 0;         // undecodable / error-flagged frames skipped
  uint64_t device_lost = 0;     // ENODEV/EIO/POLLERR events
  uint64_t reopened = 0;        // successful reopens
  uint64_t kernel_dropped = 0;  // gaps in the driver's sequence numbers
  uint64_t stale_skipped = 0;   // older queued frames skipped by newest_only
};

class V4l2Source final : public FrameSource {
 public:
  // Opens `device` and starts streaming. `default_width/height` apply when params.width/
  // height are 0 (the camera section's size). Throws std::runtime_error naming the device
  // and the reason (start-up boundary).
  V4l2Source(const std::string& device, const V4l2Params& params, int default_width,
             int default_height, V4l2Syscalls& sys);
  ~V4l2Source() override;
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;

  SourceStatus read(Frame& out, int timeout_ms) override;
  const SourceInfo& info() const override { return info_; }
  SourceCounters counters() const override;
  V4l2Stats stats() const;
  // Negotiated V4L2 pixel format as a FourCC string ("MJPG", "YUYV", "GREY").
  std::string fourcc() const;
  // What start-up did with each configured control ("exposure_us=5000: set ...").
  const std::vector<std::string>& control_report() const { return control_report_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  SourceInfo info_;
  std::vector<std::string> control_report_;
};

// Opens `v4l2:` URIs (path after the scheme); used by drivers/source_factory.cpp.
std::unique_ptr<FrameSource> open_v4l2_source(const std::string& device, const V4l2Params& params,
                                              int default_width, int default_height);

// ---- device listing for `rdslam sources` ----
struct V4l2SizeInfo {
  int width = 0;
  int height = 0;
  std::vector<double> fps;  // discrete rates, highest first; empty if the driver has none
  std::string fps_range;    // stepwise/continuous interval range as text, else empty
};

struct V4l2FormatInfo {
  std::string fourcc;       // "MJPG"
  std::string description;  // driver's text, e.g. "Motion-JPEG"
  bool usable = false;      // rdslam decodes it (MJPG, YUYV, GREY)
  std::vector<V4l2SizeInfo> sizes;
  std::string size_range;  // stepwise/continuous size range as text, else empty
};

struct V4l2DeviceInfo {
  std::string path;
  std::string card;      // VIDIOC_QUERYCAP card name
  std::string driver;    // e.g. "uvcvideo"
  std::string bus;       // e.g. "usb-0000:00:14.0-1"
  bool capture = false;  // a video capture node with streaming I/O
  std::string note;      // why it is not usable, or empty
  std::vector<V4l2FormatInfo> formats;
};

// Queries every /dev/videoN. Start-up/CLI only (allocates).
std::vector<V4l2DeviceInfo> list_v4l2_devices(V4l2Syscalls& sys);
// Human-readable listing (what `rdslam sources` prints), with a ready-to-use --set line per
// usable device; a clear message when there is none.
std::string describe_v4l2_devices(const std::vector<V4l2DeviceInfo>& devices);

}  // namespace rdslam
