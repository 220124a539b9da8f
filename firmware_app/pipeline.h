// The real-time pipeline of `rdslam run` and `rdslam replay`: fixed memory, pinned threads,
// lock-free rings (the design card: capture, tracker and mapper on pinned cores, connected
// by fixed-memory ring buffers, publishing poses).
//
//   capture ──SlotRing(slot idx)──> tracker ──SpscRing<OutputMsg>──> publisher ──> sinks
//      ^                               │  └──SpscRing<ctl>──> mapper (MapperStage::step loop)
//      └──── FramePool free list <─────┘
//
// - capture: FrameSource::read() into a pool slot, pushes the slot index. When the tracker
//   is behind and no slot is free, the capture thread evicts the OLDEST queued frame and
//   reuses its slot ("newest frame wins"; counted as dropped_capture).
// - tracker: takes the newest queued frame (older queued ones are released and counted as
//   dropped_tracker), calls TrackerStage::track(), hands a FrameResult to the publisher ring
//   (never blocks: a full ring counts publish_overflows), returns the slot.
// - mapper: calls MapperStage::step(timeout) in a loop.
// - publisher: stamps the capture-to-publish latency, calls every PipelineSink (LCM, replay
//   collector) and, every stats period, builds a PipelineStatus (status_t, stats log line,
//   status() for the supervisor).
// In `lossless` mode (replay at speed 0) nothing is dropped: capture waits for a free slot,
// the tracker takes frames in order and waits for room in the publisher ring.
//
// End of stream is a message: the capture thread pushes SlotRing::kEndOfStream after the
// source ends or after request_stop(); the tracker forwards it to the mapper and publisher;
// each thread exits after it. Shutdown time is bounded by read_timeout_ms plus one track()
// and one mapper step.
//
// Ownership: the Pipeline owns its pool, rings and threads; it borrows the source, the
// stages and the sinks, which must outlive it. Threads: construct, add_sink(), start(),
// wait()/join() from one supervising thread; request_stop() and the counters from any
// thread; sinks are called on the publisher thread only.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "core/frame_check.h"
#include "core/frame_pool.h"
#include "core/frame_source.h"
#include "core/latency_histogram.h"
#include "core/spsc_ring.h"
#include "core/stages.h"
#include "core/trajectory.h"
#include "firmware_app/pipeline_params.h"

namespace rdslam {

// One processed frame, as published.
struct FrameResult {
  uint64_t seq = 0;             // Frame::seq from the source
  int64_t stamp_ns = 0;         // Frame::stamp_ns (capture time, source clock)
  int64_t dataset_index = -1;   // Frame::dataset_index
  int64_t arrival_mono_ns = 0;  // CLOCK_MONOTONIC when the frame entered rdslam
  int64_t tracked_mono_ns = 0;  // CLOCK_MONOTONIC when track() returned
  int64_t track_ns = 0;         // duration of TrackerStage::track() for this frame
  int64_t publish_mono_ns = 0;  // CLOCK_MONOTONIC when the publisher took it
  int64_t latency_ns() const { return publish_mono_ns - arrival_mono_ns; }
  TrackResult result;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

enum PipelineThread : int { kCaptureThread = 0, kTrackerThread, kMapperThread, kPublisherThread };
constexpr int kPipelineThreads = 4;
const char* to_string(PipelineThread t);

// Health of the pipeline at one instant; percentiles and fps cover the last stats period.
struct PipelineStatus {
  int64_t mono_ns = 0;         // CLOCK_MONOTONIC of this report
  bool running = false;        // threads started and not all finished
  bool end_of_stream = false;  // the source ended (or a stop was requested) and it drained
  TrackingState state = TrackingState::kInitializing;  // of the last processed frame
  double fps = 0.0;  // processed frames per second over the last period
  double latency_p50_ms = 0, latency_p99_ms = 0;  // capture-to-publish
  double tracker_p50_ms = 0, tracker_p99_ms = 0;  // TrackerStage::track()
  uint64_t frames_captured = 0;
  uint64_t frames_processed = 0;
  // Every frame the source had that was not processed: source_skipped + dropped_capture +
  // dropped_tracker, so that at the end
  //   frames_captured + source_skipped == frames_processed + frames_dropped
  // (frames_captured counts what the capture thread received; skipped frames never reach it).
  uint64_t frames_dropped = 0;
  uint64_t dropped_capture = 0;  // evicted by capture: no free slot (tracker far behind)
  uint64_t dropped_tracker = 0;  // skipped by the tracker: a newer frame was queued
  uint64_t source_faults = 0;
  uint64_t source_timeouts = 0;
  uint64_t source_skipped = 0;     // passed over by a paced replay source that fell behind
  uint64_t publish_overflows = 0;  // processed, but the result was lost (publisher ring full)
  uint64_t frames_published = 0;   // results handed to the sinks
  // Frame checks on the capture thread (core/frame_check.h). Rejected frames are not
  // captured (not in frames_captured, so not in the books above).
  uint64_t frames_invalid = 0;   // rejected: zero-size, wrong pixel type or size
  uint64_t stamps_rejected = 0;  // rejected: stamp not after the last accepted frame's
  uint64_t frames_blank = 0;     // captured, but no contrast (black, saturated, covered)
  uint64_t exposure_jumps = 0;   // captured, mean brightness jumped > 2x against the last
  uint64_t source_reopens = 0;   // FrameSource::counters().reopens (camera came back)
  uint64_t last_seq = 0;         // seq of the last processed frame
  int map_points = 0;
  int keyframes = 0;
  int64_t invalidated_points = 0;
  double cpu_s[kPipelineThreads] = {0, 0, 0, 0};  // CPU time per thread since start
  uint32_t map_epoch = 0;  // of the last processed frame (TrackResult::epoch)
};

// Live totals since start (any thread; each counter is exact, the set is not one instant).
// After the run: captured + source_skipped == processed + dropped(), and
// processed == published + publish_overflows.
struct PipelineCounters {
  uint64_t captured = 0;
  uint64_t processed = 0;
  uint64_t published = 0;
  uint64_t dropped_capture = 0;
  uint64_t dropped_tracker = 0;
  uint64_t source_faults = 0;
  uint64_t source_timeouts = 0;
  uint64_t source_skipped = 0;
  uint64_t publish_overflows = 0;
  uint64_t frames_invalid = 0;  // as in PipelineStatus
  uint64_t stamps_rejected = 0;
  uint64_t frames_blank = 0;
  uint64_t exposure_jumps = 0;
  uint64_t source_reopens = 0;
  uint64_t dropped() const { return source_skipped + dropped_capture + dropped_tracker; }
};

// Whole-run stage timing (replay report, bench).
struct StageStats {
  LatencyHistogram::Snapshot capture_read;  // FrameSource::read() (includes waiting for a frame)
  LatencyHistogram::Snapshot tracker;       // TrackerStage::track()
  LatencyHistogram::Snapshot mapper;        // MapperStage::step() calls that did work
  LatencyHistogram::Snapshot publish;       // all sinks for one frame
  LatencyHistogram::Snapshot latency;       // capture-to-publish
};

class PipelineSink {
 public:
  virtual ~PipelineSink() = default;
  // Publisher thread, once per processed frame, in processing order. Runs on the
  // capture-to-publish path: must not allocate after warm-up and should not block.
  virtual void on_frame(const FrameResult& r) = 0;
  // Publisher thread, every stats period and once at the end (status.running == false).
  virtual void on_status(const PipelineStatus& /*status*/) {}
};

struct PipelineOptions {
  PipelineParams params;
  ThreadParams threads;
  bool lossless = false;  // never drop (replay at speed 0); otherwise newest frame wins
};

class Pipeline {
 public:
  // Allocates the frame pool (pool_slots frames of the source's size and format) and the
  // rings. Throws std::invalid_argument on unusable options (start-up boundary).
  Pipeline(FrameSource& source, TrackerStage& tracker, MapperStage& mapper,
           const PipelineOptions& options);
  ~Pipeline();  // request_stop() + join()
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  // Before start(): sinks are called in the order added.
  void add_sink(PipelineSink* sink);
  // Sets OpenCV's thread pool to opencv_threads_for(options.threads) (process-wide), starts
  // publisher, mapper, tracker, capture (consumers first), waits until each thread applied its
  // name, affinity and priority, logs the thread table. Call once.
  void start();
  // Any thread, idempotent, async-signal-safe (one atomic store): the capture thread stops
  // reading and sends end of stream through the pipeline.
  void request_stop() { stop_requested_.store(true, std::memory_order_release); }
  bool stop_requested() const { return stop_requested_.load(std::memory_order_acquire); }
  // Supervising thread: wait up to `timeout_ms` for every thread to finish; true if so.
  bool wait(int timeout_ms);
  // Supervising thread: joins every thread (after end of stream or request_stop()).
  void join();

  // Observer hooks (any thread; cheap atomics).
  bool running() const { return started_ && !finished_.load(std::memory_order_acquire); }
  bool finished() const { return finished_.load(std::memory_order_acquire); }
  uint64_t frames_captured() const { return captured_.load(std::memory_order_acquire); }
  uint64_t frames_processed() const { return processed_.load(std::memory_order_acquire); }
  PipelineCounters counters() const;
  // Latest periodic status (updated every stats period by the publisher thread and once at
  // the end). Any thread; copies under a mutex the publisher holds for a few microseconds.
  PipelineStatus status() const;
  // Whole-run stage histograms; exact after join().
  StageStats stage_stats() const;

 private:
  struct OutputMsg {
    bool end_of_stream = false;
    FrameResult frame;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  struct ThreadState {
    ThreadSpec spec;
    std::thread thread;
    clockid_t cpu_clock{};
    std::atomic<bool> cpu_clock_valid{false};
    std::atomic<int64_t> final_cpu_ns{0};
    // Set by the thread itself at start-up (read after the start-up handshake).
    int tid = 0;
    bool affinity_applied = false;
    bool fifo_applied = false;
    bool nice_applied = false;
  };

  void thread_main(PipelineThread which);
  void setup_thread(PipelineThread which);
  void capture_loop();
  bool capture_next_slot(uint32_t& slot);
  void tracker_loop();
  void mapper_loop();
  void publisher_loop();
  void process_frame(uint32_t slot);
  void send_output_eos();
  void build_status(PipelineStatus& s, int64_t now_ns, bool final_report);
  void publish_status(int64_t now_ns, bool final_report);
  void log_thread_table() const;
  double thread_cpu_s(int i) const;

  FrameSource& source_;
  TrackerStage& tracker_;
  MapperStage& mapper_;
  const PipelineOptions options_;
  std::vector<PipelineSink*> sinks_;

  FramePool pool_;
  FrameCheck frame_check_;  // capture thread
  SlotRing frames_;         // capture -> tracker
  Doorbell frames_bell_;
  SpscRing<OutputMsg> output_;  // tracker -> publisher
  Doorbell output_bell_;
  Doorbell output_space_bell_;    // lossless mode: publisher freed room
  SpscRing<uint8_t> mapper_ctl_;  // tracker -> mapper: end of stream

  ThreadState threads_[kPipelineThreads];
  int opencv_threads_ = 0;  // what start() gave cv::setNumThreads
  bool started_ = false;
  bool joined_ = false;
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> finished_{false};
  std::atomic<int> alive_{0};
  std::mutex lifecycle_mutex_;  // start-up handshake and wait(); never on the frame path
  std::condition_variable lifecycle_cv_;
  int threads_ready_ = 0;

  // Counters: each written by one thread, read by any.
  std::atomic<uint64_t> captured_{0};
  std::atomic<uint64_t> processed_{0};
  std::atomic<uint64_t> published_{0};
  std::atomic<uint64_t> dropped_capture_{0};
  std::atomic<uint64_t> dropped_tracker_{0};
  std::atomic<uint64_t> source_faults_{0};
  std::atomic<uint64_t> source_timeouts_{0};
  std::atomic<uint64_t> source_skipped_{0};  // copied from FrameSource::counters()
  std::atomic<uint64_t> publish_overflows_{0};
  std::atomic<uint64_t> frames_invalid_{0};
  std::atomic<uint64_t> stamps_rejected_{0};
  std::atomic<uint64_t> frames_blank_{0};
  std::atomic<uint64_t> exposure_jumps_{0};
  std::atomic<uint64_t> source_reopens_{0};  // copied from FrameSource::counters()
  std::atomic<uint64_t> last_seq_{0};
  std::atomic<int> last_state_{0};
  std::atomic<int> map_points_{0};
  std::atomic<int> keyframes_{0};
  std::atomic<uint32_t> map_epoch_{0};
  std::atomic<int64_t> invalidated_points_{0};
  std::atomic<bool> end_of_stream_{false};

  LatencyHistogram capture_hist_;  // capture thread
  LatencyHistogram tracker_hist_;  // tracker thread
  LatencyHistogram mapper_hist_;   // mapper thread
  LatencyHistogram publish_hist_;  // publisher thread
  LatencyHistogram latency_hist_;  // publisher thread

  // Publisher thread's interval bookkeeping.
  LatencyHistogram::Snapshot prev_latency_, prev_tracker_;
  uint64_t prev_processed_ = 0;
  int64_t prev_status_ns_ = 0;
  int64_t start_ns_ = 0;

  mutable std::mutex status_mutex_;
  PipelineStatus status_;
};

// Runs a whole recorded source through a Pipeline and returns every published result.
// The pacing is the source's (SourceOptions::speed when it was opened): pass
// options.lossless = true for speed 0 so that no frame is dropped. `cancel` (optional) is
// polled every 100 ms; setting it stops the run early. Extra sinks (e.g. LCM) see the same
// results. This is the engine of `rdslam replay` and `rdslam bench pipeline`.
struct ReplayReport {
  std::vector<FrameResult, Eigen::aligned_allocator<FrameResult>> frames;
  PipelineStatus status;  // final totals
  StageStats stages;
  double wall_s = 0.0;  // start() to join()
};
ReplayReport replay_source(FrameSource& source, TrackerStage& tracker, MapperStage& mapper,
                           const PipelineOptions& options,
                           const std::vector<PipelineSink*>& sinks = {},
                           const std::atomic<bool>* cancel = nullptr);

// The poses of the tracked frames (TRACKING, RELOCALIZED). With `final_map` null, the online
// trajectory: each pose as published. Otherwise the final trajectory (ORB-SLAM's per-frame
// trajectory): each tracked frame's pose relative to its reference keyframe when it was
// tracked (TrackResult::ref_keyframe), composed with that keyframe's pose in the final map,
// after every later bundle adjustment; frames whose reference keyframe is not in the final map
// (another map epoch, none) keep their online pose. `final_map` must have had
// set_keep_trail(true) before the run and must have stopped.
Trajectory replay_trajectory(const ReplayReport& rr, const MapperStage* final_map = nullptr);

// The size of OpenCV's thread pool for `threads` (ThreadParams::opencv_threads): the value
// when it is >= 0; for -1, the number of cores the pipeline threads may use: the cores of the
// union of their core sets that are in this process's CPU mask (sched_getaffinity; at least
// 1), or every core of that mask when one thread has no core set. 0 = OpenCV runs everything
// in the calling thread. OpenCV's worker threads are TBB's (Debian's OpenCV), which set their
// own affinity to the process's mask, so this limits how many run, not where; a core kept
// free of them needs the process mask (taskset, systemd CPUAffinity=). Start-up only.
int opencv_threads_for(const ThreadParams& threads);

}  // namespace rdslam
