// Publishes what a viewer shows (issue 26; `rdslam view`, docs/viewer.md): at viewer.image_hz
// the annotated camera image (the debug video's drawing, firmware_app/debug_video.h: inliers,
// rejected matches, map points, recently invalidated points in red, header) as a JPEG
// bot_core.image_t on lcm.image_channel, and at viewer.map_hz an rdslam.map_t (keyframe
// poses, a sample of at most viewer.map_max_points map points with their validity) on
// lcm.map_channel.
//
// Off the capture-to-publish path: it is the tracker's DebugFrameSink (core/debug_frame.h)
// in the recycling mode. It owns two preallocated records; on the tracker thread,
// acquire_record() lends a free one only when an image or map is due (else the tracker skips
// the record), the tracker copies the frame into it in place (no allocation once the record
// has the frame's size) and submit_record() pushes its index through a lock-free SPSC ring
// and rings a doorbell. Neither call blocks or allocates: with no free record (the viewer
// thread is still encoding) the frame is skipped and counted. The viewer thread of its own
// (normal scheduling, nice 10) draws, downscales, encodes the JPEG (this allocates, on that
// thread only), builds the map message and sends both with its own lcm_t, then returns the
// record through a second SPSC ring. A subscriber, slow or absent, cannot reach the
// pipeline: LCM's UDP multicast send does not wait for receivers.
//
// Ownership: owns its records, rings, renderer, lcm_t and thread. Threads: construct (throws
// std::runtime_error when the LCM URL cannot be opened), stop() and destroy on the
// supervising thread; acquire_record()/submit_record() on the tracker thread only; the
// counters from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#include "core/camera.h"
#include "core/debug_frame.h"
#include "core/spsc_ring.h"
#include "firmware_app/config.h"

typedef struct _lcm_t lcm_t;

namespace rdslam {

class DebugRenderer;

struct ViewerPublisherStats {
  uint64_t records = 0;       // records the tracker filled
  uint64_t skipped_busy = 0;  // due, but no free record (the viewer thread was behind)
  uint64_t images = 0;        // bot_core.image_t sent
  uint64_t maps = 0;          // rdslam.map_t sent
  uint64_t send_failures = 0;
  uint64_t last_image_bytes = 0;
  uint64_t max_image_bytes = 0;
  uint64_t max_map_bytes = 0;
};

class ViewerPublisher final : public DebugFrameSink {
 public:
  ViewerPublisher(const LcmParams& lcm, const ViewerParams& params, const CameraModel& camera);
  ~ViewerPublisher() override;  // stop()
  ViewerPublisher(const ViewerPublisher&) = delete;
  ViewerPublisher& operator=(const ViewerPublisher&) = delete;

  // Tracker thread (the recycling DebugFrameSink interface).
  bool recycles_records() const override { return true; }
  DebugFrame* acquire_record(const Frame& frame) override;
  void submit_record(DebugFrame* record) override;
  void on_debug_frame(DebugFrame&& frame) override;  // not called in the recycling mode

  // Supervising thread, after the pipeline joined: publishes what is queued and joins the
  // viewer thread. Idempotent.
  void stop();
  ViewerPublisherStats stats() const;

 private:
  static constexpr int kRecords = 2;
  void worker();
  void process(DebugFrame& d, int64_t lent_ns);
  bool send(const char* channel, const std::vector<uint8_t>& buf);

  const LcmParams lcm_params_;
  const ViewerParams params_;
  const CameraModel camera_;
  lcm_t* lcm_ = nullptr;
  std::unique_ptr<DebugRenderer> renderer_;  // viewer thread
  std::unique_ptr<DebugFrame> records_[kRecords];
  SpscRing<uint8_t> free_;    // viewer -> tracker: record indices to fill
  SpscRing<uint8_t> filled_;  // tracker -> viewer: filled records
  Doorbell filled_bell_;
  // Tracker thread: next due times (CLOCK_MONOTONIC ns) of a record.
  int64_t next_record_ns_ = 0;
  int64_t record_period_ns_ = 0;
  // When each record was lent (tracker thread; read by the viewer thread after the ring hands
  // it over): the image and map rates are kept on these times, not on the viewer thread's
  // own, so a late viewer thread does not skip a due image.
  int64_t lent_ns_[kRecords] = {};
  // Viewer thread.
  int64_t next_image_ns_ = 0, next_map_ns_ = 0;
  std::atomic<bool> stopping_{false};
  std::thread thread_;

  std::atomic<uint64_t> records_n_{0}, skipped_busy_{0}, images_{0}, maps_{0}, failures_{0};
  std::atomic<uint64_t> last_image_bytes_{0}, max_image_bytes_{0}, max_map_bytes_{0};
};

}  // namespace rdslam
