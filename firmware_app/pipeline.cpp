#include "firmware_app/pipeline.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <string>

#include <opencv2/core/utility.hpp>

#include "core/log.h"
#include "firmware_app/thread_setup.h"

namespace rdslam {

const char* to_string(PipelineThread t) {
  switch (t) {
    case kCaptureThread:
      return "capture";
    case kTrackerThread:
      return "tracker";
    case kMapperThread:
      return "mapper";
    case kPublisherThread:
      return "publisher";
  }
  return "unknown";
}

namespace {

// Kernel thread names are limited to 15 characters.
const char* const kThreadNames[kPipelineThreads] = {"rdslam-capture", "rdslam-tracker",
                                                    "rdslam-mapper", "rdslam-publish"};
// How long the tracker waits for a frame before re-checking for a stuck capture thread.
constexpr int kTrackerWaitMs = 100;

PipelineOptions checked(const PipelineOptions& o) {
  if (o.params.pool_slots < 3) {
    throw std::invalid_argument("pipeline.pool_slots: need at least 3 (write, track, queue)");
  }
  if (o.params.output_ring_capacity < 2) {
    throw std::invalid_argument("pipeline.output_ring_capacity: need at least 2");
  }
  return o;
}

int source_width(FrameSource& s) {
  return s.info().width > 0 ? s.info().width : 640;
}
int source_height(FrameSource& s) {
  return s.info().height > 0 ? s.info().height : 480;
}

std::string cores_text(const std::vector<int>& cores) {
  if (cores.empty()) return "any";
  std::string out;
  for (size_t i = 0; i < cores.size(); ++i) out += (i ? "," : "") + std::to_string(cores[i]);
  return out;
}

}  // namespace

int opencv_threads_for(const ThreadParams& threads) {
  if (threads.opencv_threads >= 0) return threads.opencv_threads;
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof(allowed), &allowed) != 0) return 1;
  cpu_set_t used;
  CPU_ZERO(&used);
  for (const ThreadSpec* t :
       {&threads.capture, &threads.tracker, &threads.mapper, &threads.publisher}) {
    if (t->cores.empty()) return std::max(1, CPU_COUNT(&allowed));  // may run anywhere
    for (int c : t->cores) {
      if (c >= 0 && c < CPU_SETSIZE && CPU_ISSET(c, &allowed)) CPU_SET(c, &used);
    }
  }
  return std::max(1, CPU_COUNT(&used));
}

Pipeline::Pipeline(FrameSource& source, TrackerStage& tracker, MapperStage& mapper,
                   const PipelineOptions& options)
    : source_(source),
      tracker_(tracker),
      mapper_(mapper),
      options_(checked(options)),
      pool_(options.params.pool_slots, source_width(source), source_height(source),
            source.info().format),
      // Room for every slot plus the end-of-stream message: a push can never fail.
      frames_(static_cast<uint32_t>(options.params.pool_slots) + 1),
      output_(static_cast<uint32_t>(options.params.output_ring_capacity)),
      mapper_ctl_(2) {
  threads_[kCaptureThread].spec = options_.threads.capture;
  threads_[kTrackerThread].spec = options_.threads.tracker;
  threads_[kMapperThread].spec = options_.threads.mapper;
  threads_[kPublisherThread].spec = options_.threads.publisher;
}

Pipeline::~Pipeline() {
  request_stop();
  join();
}

void Pipeline::add_sink(PipelineSink* sink) {
  if (started_) throw std::logic_error("Pipeline::add_sink after start()");
  if (sink) sinks_.push_back(sink);
}

void Pipeline::start() {
  if (started_) throw std::logic_error("Pipeline::start called twice");
  started_ = true;
  // Process-wide; before the threads start, so the pool never exceeds the configured cores.
  opencv_threads_ = opencv_threads_for(options_.threads);
  cv::setNumThreads(opencv_threads_);
  const int64_t now = mono_now_ns();
  start_ns_ = now;
  prev_status_ns_ = now;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    status_.mono_ns = now;
    status_.running = true;
  }
  alive_.store(kPipelineThreads);
  // Consumers first, so that nothing is produced into a ring nobody drains.
  const PipelineThread order[kPipelineThreads] = {kPublisherThread, kMapperThread, kTrackerThread,
                                                  kCaptureThread};
  for (int i = 0; i < kPipelineThreads; ++i) {
    const PipelineThread t = order[i];
    threads_[t].thread = std::thread([this, t] { thread_main(t); });
    // Wait for this thread's set-up before starting the next one: start-up order is
    // deterministic and the thread table below is complete.
    std::unique_lock<std::mutex> lock(lifecycle_mutex_);
    lifecycle_cv_.wait(lock, [&] { return threads_ready_ >= i + 1; });
  }
  log_thread_table();
}

bool Pipeline::wait(int timeout_ms) {
  if (!started_) return true;
  std::unique_lock<std::mutex> lock(lifecycle_mutex_);
  return lifecycle_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                                [&] { return finished_.load(std::memory_order_acquire); });
}

void Pipeline::join() {
  if (!started_ || joined_) return;
  for (auto& t : threads_) {
    if (t.thread.joinable()) t.thread.join();
  }
  joined_ = true;
}

void Pipeline::setup_thread(PipelineThread which) {
  ThreadState& ts = threads_[which];
  pthread_t self = pthread_self();
  pthread_setname_np(self, kThreadNames[which]);
  ts.tid = static_cast<int>(syscall(SYS_gettid));
  if (pthread_getcpuclockid(self, &ts.cpu_clock) == 0) {
    ts.cpu_clock_valid.store(true, std::memory_order_release);
  }
  if (!ts.spec.cores.empty()) {
    std::vector<int> missing;
    const int rc = pin_this_thread(ts.spec.cores, &missing);
    for (int c : missing) {
      RDSLAM_LOG_WARN("threads.%s_cores: core %d does not exist (this machine has %ld); ignored",
                      to_string(which), c, sysconf(_SC_NPROCESSORS_CONF));
    }
    ts.affinity_applied = rc == 0;
    if (rc != 0) {
      RDSLAM_LOG_WARN("threads.%s_cores: cannot pin thread to cores [%s]: %s; running unpinned",
                      to_string(which), cores_text(ts.spec.cores).c_str(), std::strerror(rc));
    }
  }
  if (ts.spec.priority > 0 && options_.lossless) {
    // A lossless replay runs as fast as the stages go, never waiting for a frame: at
    // SCHED_FIFO its threads would hold their cores for the whole run (everything else on
    // the machine starves but for the kernel's RT throttling). Real-time priorities are for
    // paced and live runs, where they bound the latency (docs/benchmarks.md).
    RDSLAM_LOG_INFO("threads.%s_priority: %d not applied in a lossless replay (normal scheduling)",
                    to_string(which), ts.spec.priority);
  } else if (ts.spec.priority > 0) {
    sched_param sp{};
    sp.sched_priority = ts.spec.priority;
    const int rc = pthread_setschedparam(self, SCHED_FIFO, &sp);
    ts.fifo_applied = rc == 0;
    if (rc != 0) {
      RDSLAM_LOG_WARN(
          "threads.%s_priority: SCHED_FIFO priority %d not permitted (%s); the %s thread runs "
          "with normal scheduling. Grant CAP_SYS_NICE or LimitRTPRIO=%d (systemd) to enable it",
          to_string(which), ts.spec.priority, std::strerror(rc), to_string(which),
          ts.spec.priority);
    }
  }
  if (ts.spec.nice != 0 && !ts.fifo_applied) {
    // A mapper at nice > 0 leaves the tracker the CPU it needs when both share a core (2-core
    // boards).
    const int rc = set_this_thread_nice(ts.spec.nice);
    ts.nice_applied = rc == 0;
    if (rc != 0) {
      RDSLAM_LOG_WARN(
          "threads.%s_nice: nice %d not permitted (%s); the %s thread keeps nice 0. Negative "
          "values need CAP_SYS_NICE or LimitNICE= (systemd)",
          to_string(which), ts.spec.nice, std::strerror(rc), to_string(which));
    }
  }
}

void Pipeline::thread_main(PipelineThread which) {
  setup_thread(which);
  {
    std::lock_guard<std::mutex> lock(lifecycle_mutex_);
    ++threads_ready_;
  }
  lifecycle_cv_.notify_all();

  switch (which) {
    case kCaptureThread:
      capture_loop();
      break;
    case kTrackerThread:
      tracker_loop();
      break;
    case kMapperThread:
      mapper_loop();
      break;
    case kPublisherThread:
      publisher_loop();
      break;
  }

  ThreadState& ts = threads_[which];
  timespec cpu{};
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu) == 0) {
    ts.final_cpu_ns.store(static_cast<int64_t>(cpu.tv_sec) * 1000000000LL + cpu.tv_nsec);
  }
  // The clock id dies with the thread: readers switch to final_cpu_ns from here on.
  ts.cpu_clock_valid.store(false, std::memory_order_release);
  if (alive_.fetch_sub(1) == 1) {
    {
      std::lock_guard<std::mutex> lock(lifecycle_mutex_);
      finished_.store(true, std::memory_order_release);
    }
    lifecycle_cv_.notify_all();
  }
}

void Pipeline::log_thread_table() const {
  RDSLAM_LOG_INFO("pipeline: %d frame slots %dx%d, %s; source %s", pool_.slots(),
                  pool_.frame(0).image.cols, pool_.frame(0).image.rows,
                  options_.lossless ? "lossless (replay speed 0)" : "newest frame wins",
                  source_.info().uri.c_str());
  RDSLAM_LOG_INFO("pipeline: OpenCV thread pool %d (threads.opencv_threads %d)", opencv_threads_,
                  options_.threads.opencv_threads);
  RDSLAM_LOG_INFO("pipeline threads:  %-15s %-8s %-12s %-8s %-8s %s", "thread", "tid", "cores",
                  "policy", "priority", "nice");
  for (int i = 0; i < kPipelineThreads; ++i) {
    const ThreadState& ts = threads_[i];
    const std::string cores = cores_text(ts.spec.cores) +
                              (ts.spec.cores.empty() || ts.affinity_applied ? "" : " (FAILED)");
    const char* policy = ts.spec.priority == 0 ? "OTHER"
                         : ts.fifo_applied     ? "FIFO"
                         : options_.lossless   ? "OTHER(lossless)"
                                               : "OTHER(!)";
    RDSLAM_LOG_INFO("pipeline threads:  %-15s %-8d %-12s %-8s %-8d %d", kThreadNames[i], ts.tid,
                    cores.c_str(), policy, ts.fifo_applied ? ts.spec.priority : 0,
                    ts.nice_applied ? ts.spec.nice : 0);
  }
}

// ---- capture ----

// Gets the slot the next frame will be read into. Called with no slot in hand, right after
// a frame was pushed, so when the pool is exhausted a NEWER frame than the evicted one is
// already queued: "newest frame wins" never drops a frame before its successor exists.
bool Pipeline::capture_next_slot(uint32_t& slot) {
  const int timeout_ms = options_.params.read_timeout_ms;
  while (!stop_requested()) {
    if (pool_.try_acquire(slot)) return true;
    if (!options_.lossless && frames_.evict_oldest(slot)) {
      dropped_capture_.fetch_add(1, std::memory_order_relaxed);
      return true;
    }
    // Every slot is with the tracker (or, lossless, queued): wait for a release.
    if (pool_.wait_acquire(slot, timeout_ms)) return true;
  }
  return false;
}

void Pipeline::capture_loop() {
  const int timeout_ms = options_.params.read_timeout_ms;
  uint32_t slot = 0;
  bool have_slot = capture_next_slot(slot);
  while (have_slot && !stop_requested()) {
    Frame& f = pool_.frame(slot);
    f.arrival_mono_ns = 0;
    const int64_t t0 = mono_now_ns();
    const SourceStatus st = source_.read(f, timeout_ms);
    const int64_t t1 = mono_now_ns();
    if (st == SourceStatus::kOk) {
      // Checks on what the source handed over (core/frame_check.h): a rejected frame keeps
      // its slot and the next read reuses it (a zero-size image is allocated again there).
      const FrameCheckResult fc = frame_check_.check(f);
      if (fc.verdict != FrameVerdict::kOk) {
        (fc.verdict == FrameVerdict::kInvalid ? frames_invalid_ : stamps_rejected_)
            .fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      if (fc.blank) frames_blank_.fetch_add(1, std::memory_order_relaxed);
      if (fc.exposure_jump) exposure_jumps_.fetch_add(1, std::memory_order_relaxed);
      if (f.arrival_mono_ns == 0) f.arrival_mono_ns = t1;
      capture_hist_.record_ns(t1 - t0);
      // The source's own skips (a paced replay that fell behind) complete the books.
      source_skipped_.store(source_.counters().skipped, std::memory_order_relaxed);
      source_reopens_.store(source_.counters().reopens, std::memory_order_relaxed);
      captured_.fetch_add(1, std::memory_order_release);
      frames_.try_push(slot);  // cannot fail: room for every slot + end of stream
      frames_bell_.ring();
      have_slot = capture_next_slot(slot);
    } else if (st == SourceStatus::kEndOfStream) {
      break;
    } else if (st == SourceStatus::kTimeout) {
      source_timeouts_.fetch_add(1, std::memory_order_relaxed);
    } else {
      source_faults_.fetch_add(1, std::memory_order_relaxed);
    }
    if (st != SourceStatus::kOk) {
      source_reopens_.store(source_.counters().reopens, std::memory_order_relaxed);
    }
  }
  // Frames a paced source passed over after the last delivered one (it fell behind at the
  // end) complete the books too; stored before end of stream so the final status has them.
  source_skipped_.store(source_.counters().skipped, std::memory_order_relaxed);
  source_reopens_.store(source_.counters().reopens, std::memory_order_relaxed);
  // A slot still in our hands is simply not returned: the pool dies with the pipeline.
  frames_.try_push(SlotRing::kEndOfStream);
  frames_bell_.ring();
}

// ---- tracker ----

void Pipeline::tracker_loop() {
  int64_t stop_seen_ns = 0;
  for (;;) {
    uint32_t slot = 0;
    if (!frames_.try_pop(slot)) {
      const uint32_t ticket = frames_bell_.ticket();
      if (!frames_.try_pop(slot)) {
        frames_bell_.wait(ticket, kTrackerWaitMs);
        // Safety net for a source whose read() ignores its timeout: after a stop request
        // the capture thread gets 2 s to deliver end of stream before the tracker leaves.
        if (stop_requested()) {
          const int64_t now = mono_now_ns();
          if (stop_seen_ns == 0) stop_seen_ns = now;
          if (now - stop_seen_ns > 2000000000LL) {
            RDSLAM_LOG_WARN("pipeline: capture thread did not end within 2 s of the stop request");
            break;
          }
        }
        continue;
      }
    }
    bool eos = slot == SlotRing::kEndOfStream;
    if (!eos && !options_.lossless) {
      // Newest frame wins: skip everything older than the newest queued frame.
      uint32_t next = 0;
      while (frames_.try_pop(next)) {
        if (next == SlotRing::kEndOfStream) {
          eos = true;  // process `slot`, the last frame, then stop
          break;
        }
        pool_.release(slot);
        dropped_tracker_.fetch_add(1, std::memory_order_relaxed);
        slot = next;
      }
      process_frame(slot);
    } else if (!eos) {
      process_frame(slot);
    }
    if (eos) break;
  }
  end_of_stream_.store(true, std::memory_order_release);
  mapper_ctl_.try_push(1);
  send_output_eos();
}

void Pipeline::process_frame(uint32_t slot) {
  const Frame& f = pool_.frame(slot);
  const int64_t t0 = mono_now_ns();
  const TrackResult r = tracker_.track(f);
  const int64_t t1 = mono_now_ns();
  tracker_hist_.record_ns(t1 - t0);

  OutputMsg* m = output_.back();
  while (!m && options_.lossless) {
    const uint32_t ticket = output_space_bell_.ticket();
    m = output_.back();
    if (m) break;
    output_space_bell_.wait(ticket, kTrackerWaitMs);
    m = output_.back();
  }
  if (m) {
    m->end_of_stream = false;
    m->frame.seq = f.seq;
    m->frame.stamp_ns = f.stamp_ns;
    m->frame.dataset_index = f.dataset_index;
    m->frame.arrival_mono_ns = f.arrival_mono_ns;
    m->frame.tracked_mono_ns = t1;
    m->frame.track_ns = t1 - t0;
    m->frame.publish_mono_ns = 0;
    m->frame.result = r;
    output_.commit();
    output_bell_.ring();
  } else {
    publish_overflows_.fetch_add(1, std::memory_order_relaxed);
  }
  last_seq_.store(f.seq, std::memory_order_relaxed);
  last_state_.store(static_cast<int>(r.state), std::memory_order_relaxed);
  map_points_.store(r.map_points, std::memory_order_relaxed);
  keyframes_.store(r.keyframes, std::memory_order_relaxed);
  map_epoch_.store(r.epoch, std::memory_order_relaxed);
  invalidated_points_.store(r.invalidated_points, std::memory_order_relaxed);
  processed_.fetch_add(1, std::memory_order_release);
  pool_.release(slot);
}

void Pipeline::send_output_eos() {
  // End of stream must reach the publisher even if the ring is momentarily full.
  for (;;) {
    const uint32_t ticket = output_space_bell_.ticket();
    if (OutputMsg* m = output_.back()) {
      m->end_of_stream = true;
      output_.commit();
      output_bell_.ring();
      return;
    }
    output_space_bell_.wait(ticket, kTrackerWaitMs);
  }
}

// ---- mapper ----

void Pipeline::mapper_loop() {
  const int timeout_ms = options_.params.mapper_step_timeout_ms;
  uint8_t msg = 0;
  for (;;) {
    const int64_t t0 = mono_now_ns();
    if (mapper_.step(timeout_ms)) mapper_hist_.record_ns(mono_now_ns() - t0);
    if (mapper_ctl_.try_pop(msg)) break;
  }
  // End of stream: finish the work already queued (bounded, so a mapper that always finds
  // work cannot hold the shutdown).
  for (int i = 0; i < 1000; ++i) {
    const int64_t t0 = mono_now_ns();
    if (!mapper_.step(0)) break;
    mapper_hist_.record_ns(mono_now_ns() - t0);
  }
}

// ---- publisher ----

void Pipeline::publisher_loop() {
  const int64_t period_ns = static_cast<int64_t>(options_.params.stats_period_ms) * 1000000LL;
  int64_t next_status_ns = mono_now_ns() + period_ns;
  for (;;) {
    OutputMsg* m = output_.front();
    if (m) {
      if (m->end_of_stream) {
        output_.pop();
        output_space_bell_.ring();
        break;
      }
      FrameResult& fr = m->frame;
      fr.publish_mono_ns = mono_now_ns();
      latency_hist_.record_ns(fr.latency_ns());
      for (PipelineSink* s : sinks_) s->on_frame(fr);
      publish_hist_.record_ns(mono_now_ns() - fr.publish_mono_ns);
      output_.pop();
      output_space_bell_.ring();
      published_.fetch_add(1, std::memory_order_release);
    } else {
      const uint32_t ticket = output_bell_.ticket();
      if (!output_.front()) {
        const int64_t wait_ns = next_status_ns - mono_now_ns();
        if (wait_ns > 0) output_bell_.wait(ticket, static_cast<int>(wait_ns / 1000000 + 1));
      }
    }
    const int64_t now = mono_now_ns();
    if (now >= next_status_ns) {
      publish_status(now, false);
      next_status_ns += period_ns;
      if (next_status_ns <= now) next_status_ns = now + period_ns;  // after a long stall
    }
  }
  publish_status(mono_now_ns(), true);
}

double Pipeline::thread_cpu_s(int i) const {
  const ThreadState& ts = threads_[i];
  if (ts.cpu_clock_valid.load(std::memory_order_acquire)) {
    timespec cpu{};
    if (clock_gettime(ts.cpu_clock, &cpu) == 0) return cpu.tv_sec + cpu.tv_nsec * 1e-9;
  }
  return ts.final_cpu_ns.load() * 1e-9;
}

void Pipeline::build_status(PipelineStatus& s, int64_t now_ns, bool final_report) {
  const LatencyHistogram::Snapshot lat = latency_hist_.snapshot();
  const LatencyHistogram::Snapshot trk = tracker_hist_.snapshot();
  // The final report summarises the whole run; periodic ones the last period.
  const LatencyHistogram::Snapshot dlat = final_report ? lat : lat.since(prev_latency_);
  const LatencyHistogram::Snapshot dtrk = final_report ? trk : trk.since(prev_tracker_);
  const uint64_t processed = processed_.load(std::memory_order_acquire);
  s.mono_ns = now_ns;
  s.running = !final_report;
  s.end_of_stream = end_of_stream_.load(std::memory_order_acquire);
  s.state = static_cast<TrackingState>(last_state_.load(std::memory_order_relaxed));
  const double dt_s = (now_ns - prev_status_ns_) * 1e-9;
  const double run_s = (now_ns - start_ns_) * 1e-9;
  // Periodic reports: the last period; the final report: the whole run.
  if (final_report) {
    s.fps = run_s > 0 ? processed / run_s : 0.0;
  } else {
    s.fps = dt_s > 0 ? (processed - prev_processed_) / dt_s : 0.0;
  }
  s.latency_p50_ms = dlat.percentile_ms(0.50);
  s.latency_p99_ms = dlat.percentile_ms(0.99);
  s.tracker_p50_ms = dtrk.percentile_ms(0.50);
  s.tracker_p99_ms = dtrk.percentile_ms(0.99);
  s.frames_captured = captured_.load(std::memory_order_acquire);
  s.frames_processed = processed;
  s.dropped_capture = dropped_capture_.load(std::memory_order_relaxed);
  s.dropped_tracker = dropped_tracker_.load(std::memory_order_relaxed);
  s.source_faults = source_faults_.load(std::memory_order_relaxed);
  s.source_timeouts = source_timeouts_.load(std::memory_order_relaxed);
  s.source_skipped = source_skipped_.load(std::memory_order_relaxed);
  s.frames_dropped = s.source_skipped + s.dropped_capture + s.dropped_tracker;
  s.publish_overflows = publish_overflows_.load(std::memory_order_relaxed);
  s.frames_published = published_.load(std::memory_order_acquire);
  s.frames_invalid = frames_invalid_.load(std::memory_order_relaxed);
  s.stamps_rejected = stamps_rejected_.load(std::memory_order_relaxed);
  s.frames_blank = frames_blank_.load(std::memory_order_relaxed);
  s.exposure_jumps = exposure_jumps_.load(std::memory_order_relaxed);
  s.source_reopens = source_reopens_.load(std::memory_order_relaxed);
  s.last_seq = last_seq_.load(std::memory_order_relaxed);
  s.map_points = map_points_.load(std::memory_order_relaxed);
  s.keyframes = keyframes_.load(std::memory_order_relaxed);
  s.map_epoch = map_epoch_.load(std::memory_order_relaxed);
  s.invalidated_points = invalidated_points_.load(std::memory_order_relaxed);
  for (int i = 0; i < kPipelineThreads; ++i) s.cpu_s[i] = thread_cpu_s(i);
  prev_latency_ = lat;
  prev_tracker_ = trk;
  prev_processed_ = processed;
  prev_status_ns_ = now_ns;
}

void Pipeline::publish_status(int64_t now_ns, bool final_report) {
  PipelineStatus s;
  build_status(s, now_ns, final_report);
  for (PipelineSink* sink : sinks_) sink->on_status(s);
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    status_ = s;
  }
  if (log_level() > LogLevel::kInfo) return;
  // Formatted in short pieces on the stack: glibc's printf allocates a scratch buffer for
  // formats with many conversions, and this line is on the publisher thread (no heap).
  char line[1024];  // the longest line (20-digit counters) is about 700 characters
  int n = std::snprintf(line, sizeof(line), "stats%s: %s fps %.1f captured %llu processed %llu",
                        final_report ? " (total)" : "", to_string(s.state), s.fps,
                        static_cast<unsigned long long>(s.frames_captured),
                        static_cast<unsigned long long>(s.frames_processed));
  n += std::snprintf(line + n, sizeof(line) - n,
                     " dropped %llu (source skipped %llu, capture %llu, tracker %llu)",
                     static_cast<unsigned long long>(s.frames_dropped),
                     static_cast<unsigned long long>(s.source_skipped),
                     static_cast<unsigned long long>(s.dropped_capture),
                     static_cast<unsigned long long>(s.dropped_tracker));
  n += std::snprintf(line + n, sizeof(line) - n, " faults %llu overflows %llu",
                     static_cast<unsigned long long>(s.source_faults),
                     static_cast<unsigned long long>(s.publish_overflows));
  n += std::snprintf(line + n, sizeof(line) - n,
                     " rejected %llu/%llu (invalid/stamp) blank %llu exposure jumps %llu",
                     static_cast<unsigned long long>(s.frames_invalid),
                     static_cast<unsigned long long>(s.stamps_rejected),
                     static_cast<unsigned long long>(s.frames_blank),
                     static_cast<unsigned long long>(s.exposure_jumps));
  n += std::snprintf(line + n, sizeof(line) - n,
                     " latency p50/p99 %.2f/%.2f ms tracker p50/p99 %.2f/%.2f ms", s.latency_p50_ms,
                     s.latency_p99_ms, s.tracker_p50_ms, s.tracker_p99_ms);
  std::snprintf(line + n, sizeof(line) - n,
                " cpu capture/tracker/mapper/publisher %.2f/%.2f/%.2f/%.2f s", s.cpu_s[0],
                s.cpu_s[1], s.cpu_s[2], s.cpu_s[3]);
  RDSLAM_LOG_INFO("%s", line);
}

PipelineStatus Pipeline::status() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return status_;
}

PipelineCounters Pipeline::counters() const {
  PipelineCounters c;
  c.captured = captured_.load(std::memory_order_acquire);
  c.processed = processed_.load(std::memory_order_acquire);
  c.published = published_.load(std::memory_order_acquire);
  c.dropped_capture = dropped_capture_.load(std::memory_order_relaxed);
  c.dropped_tracker = dropped_tracker_.load(std::memory_order_relaxed);
  c.source_faults = source_faults_.load(std::memory_order_relaxed);
  c.source_timeouts = source_timeouts_.load(std::memory_order_relaxed);
  c.source_skipped = source_skipped_.load(std::memory_order_relaxed);
  c.publish_overflows = publish_overflows_.load(std::memory_order_relaxed);
  c.frames_invalid = frames_invalid_.load(std::memory_order_relaxed);
  c.stamps_rejected = stamps_rejected_.load(std::memory_order_relaxed);
  c.frames_blank = frames_blank_.load(std::memory_order_relaxed);
  c.exposure_jumps = exposure_jumps_.load(std::memory_order_relaxed);
  c.source_reopens = source_reopens_.load(std::memory_order_relaxed);
  return c;
}

StageStats Pipeline::stage_stats() const {
  StageStats s;
  s.capture_read = capture_hist_.snapshot();
  s.tracker = tracker_hist_.snapshot();
  s.mapper = mapper_hist_.snapshot();
  s.publish = publish_hist_.snapshot();
  s.latency = latency_hist_.snapshot();
  return s;
}

// ---- replay ----

namespace {
class CollectSink : public PipelineSink {
 public:
  explicit CollectSink(ReplayReport& report) : report_(report) {}
  void on_frame(const FrameResult& r) override { report_.frames.push_back(r); }

 private:
  ReplayReport& report_;
};
}  // namespace

ReplayReport replay_source(FrameSource& source, TrackerStage& tracker, MapperStage& mapper,
                           const PipelineOptions& options, const std::vector<PipelineSink*>& sinks,
                           const std::atomic<bool>* cancel) {
  ReplayReport report;
  const int64_t expected = source.info().frame_count;
  // Reserve up front so the collector does not reallocate during the run.
  report.frames.reserve(expected > 0 ? static_cast<size_t>(expected) : 4096);
  CollectSink collect(report);
  Pipeline pipeline(source, tracker, mapper, options);
  pipeline.add_sink(&collect);
  for (PipelineSink* s : sinks) pipeline.add_sink(s);
  const int64_t t0 = mono_now_ns();
  pipeline.start();
  while (!pipeline.wait(100)) {
    if (cancel && cancel->load()) pipeline.request_stop();
  }
  pipeline.join();
  report.wall_s = (mono_now_ns() - t0) * 1e-9;
  report.status = pipeline.status();
  report.stages = pipeline.stage_stats();
  return report;
}

Trajectory replay_trajectory(const ReplayReport& rr, const MapperStage* final_map) {
  Trajectory out;
  for (const auto& f : rr.frames) {
    if (f.result.state != TrackingState::kTracking &&
        f.result.state != TrackingState::kRelocalized) {
      continue;
    }
    StampedPose sp;
    sp.stamp_ns = f.stamp_ns;
    sp.p_world_cam = f.result.p_world_cam;
    sp.q_world_cam = f.result.q_world_cam;
    Pose T_world_cam;  // re-anchored on the reference keyframe in the final map
    if (final_map != nullptr && final_map->final_frame_pose(f.result, &T_world_cam)) {
      sp.q_world_cam = Eigen::Quaterniond(T_world_cam.R).normalized();
      sp.p_world_cam = T_world_cam.t;
    }
    out.push_back(sp);
  }
  return out;
}

}  // namespace rdslam
