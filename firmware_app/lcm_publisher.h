// Publishes the pipeline's output over LCM (issue 9 item 4): rdslam.pose_t (version
// pose_t::VERSION, with the map epoch and the pose covariance of the TrackResult) on
// lcm.pose_channel for every processed frame, rdslam.status_t on lcm.status_channel every
// stats period (1 Hz), and optionally a libbot2-compatible bot_core.pose_t on
// lcm.bot_core_pose_channel.
//
// It is a PipelineSink, so it runs on the pipeline's publisher thread: the tracker hands
// its results over through the pipeline's SPSC ring of preallocated messages and never
// waits for the network. Messages are encoded into a preallocated buffer and sent with the
// C API's lcm_publish(): no heap allocation per message (the C++ lcm::LCM::publish(msg)
// would allocate an encode buffer each time). A failed send is counted, never fatal.
//
// Ownership: owns its lcm_t. Threads: construct on the start-up thread (throws
// std::runtime_error when the LCM URL cannot be opened); on_frame()/on_status() on the
// publisher thread only; counters from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "firmware_app/config.h"
#include "firmware_app/pipeline.h"

typedef struct _lcm_t lcm_t;

namespace rdslam {

class LcmPublisher : public PipelineSink {
 public:
  explicit LcmPublisher(const LcmParams& params);
  ~LcmPublisher() override;
  LcmPublisher(const LcmPublisher&) = delete;
  LcmPublisher& operator=(const LcmPublisher&) = delete;

  void on_frame(const FrameResult& r) override;
  void on_status(const PipelineStatus& s) override;

  uint64_t poses_published() const { return poses_.load(std::memory_order_relaxed); }
  uint64_t statuses_published() const { return statuses_.load(std::memory_order_relaxed); }
  uint64_t send_failures() const { return failures_.load(std::memory_order_relaxed); }

 private:
  bool send(const std::string& channel, const void* data, int size);

  const LcmParams params_;
  lcm_t* lcm_ = nullptr;
  // Largest message is rdslam.pose_t: 4 + 8+8+8 + 24 + 32 + 288 + 8 + 4 + 1 + 8 bytes plus
  // the 8-byte fingerprint: well under 1 KiB.
  alignas(8) uint8_t buf_[1024];
  std::atomic<uint64_t> poses_{0};
  std::atomic<uint64_t> statuses_{0};
  std::atomic<uint64_t> failures_{0};
};

}  // namespace rdslam
