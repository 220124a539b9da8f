// Pipeline runtime (firmware_app/pipeline.h): lossless replay, "newest frame wins" with
// exact drop counts, end of stream and stop, never-blocking publication, thread set-up.
// Assertions are on counts and sequence numbers, never on wall-clock thresholds (except the
// issue's "stop within 2 s" contract).
#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "drivers/replay_source.h"
#include "firmware_app/passthrough_stages.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/progress.h"
#include "tests/unit/pipeline_fakes.h"

namespace rdslam {
namespace {

using testing_fakes::CountingSource;
using testing_fakes::eventually;
using testing_fakes::GatedSource;
using testing_fakes::IdleMapper;
using testing_fakes::RecordingSink;
using testing_fakes::ScriptedTracker;
using testing_fakes::SkippingSource;

PipelineOptions small_options(bool lossless) {
  PipelineOptions o;
  o.params.pool_slots = 8;
  o.params.output_ring_capacity = 64;
  o.params.read_timeout_ms = 20;
  o.params.mapper_step_timeout_ms = 20;
  o.params.stats_period_ms = 100;
  o.lossless = lossless;
  return o;
}

TEST(Pipeline, LosslessReplayDeliversEveryFrameInOrder) {
  CountingSource source(500);
  ScriptedTracker tracker;
  IdleMapper mapper;
  RecordingSink sink;
  const ReplayReport rep = replay_source(source, tracker, mapper, small_options(true), {&sink});
  ASSERT_EQ(rep.frames.size(), 500u);
  for (size_t i = 0; i < rep.frames.size(); ++i) {
    ASSERT_EQ(rep.frames[i].seq, i);
    ASSERT_EQ(rep.frames[i].stamp_ns, static_cast<int64_t>(i) * 33333333);
    ASSERT_EQ(rep.frames[i].result.p_world_cam.x(), static_cast<double>(i));
  }
  EXPECT_EQ(sink.seqs_.size(), 500u) << "extra sinks see the same results";
  EXPECT_TRUE(sink.pose_matches_seq_);
  EXPECT_TRUE(sink.latency_ok_) << "arrival <= tracked <= published on CLOCK_MONOTONIC";
  EXPECT_EQ(rep.status.frames_captured, 500u);
  EXPECT_EQ(rep.status.frames_processed, 500u);
  EXPECT_EQ(rep.status.frames_published, 500u);
  EXPECT_EQ(rep.status.frames_dropped, 0u);
  EXPECT_EQ(rep.status.publish_overflows, 0u);
  EXPECT_TRUE(rep.status.end_of_stream);
  EXPECT_FALSE(rep.status.running);
  EXPECT_EQ(rep.stages.tracker.total, 500u);
  EXPECT_EQ(rep.stages.latency.total, 500u);
  EXPECT_EQ(rep.stages.capture_read.total, 500u);
  EXPECT_FALSE(sink.last_status_.running) << "the final status comes last";
  EXPECT_EQ(sink.last_status_.frames_processed, 500u);
}

// The tracker is held inside track() by the test while the source produces frames: when it
// is let go it must receive the newest frame, and every frame in between is counted as
// dropped exactly once (by the capture thread when the pool ran out, or by the tracker).
TEST(Pipeline, NewestFrameWinsAndDropsAreCountedExactly) {
  GatedSource source(26);
  ScriptedTracker tracker(/*gated=*/true);
  IdleMapper mapper;
  RecordingSink sink;
  Pipeline p(source, tracker, mapper, small_options(false));  // 8 slots
  p.add_sink(&sink);
  p.start();

  source.allow(1);
  ASSERT_EQ(tracker.wait_entered(1), (std::vector<uint64_t>{0}));

  // Frames 1..5 arrive while frame 0 is being tracked; 8 slots hold them all.
  source.allow(6);
  ASSERT_TRUE(eventually([&] { return p.counters().captured == 6; }));
  tracker.release_one();
  ASSERT_EQ(tracker.wait_entered(2), (std::vector<uint64_t>{0, 5}));
  EXPECT_EQ(p.counters().dropped_tracker, 4u);  // 1, 2, 3, 4
  EXPECT_EQ(p.counters().dropped_capture, 0u);

  // Frames 6..25 while frame 5 is tracked. Slots: tracker 1, capture's spare 1, so 6 more
  // queue up (6..11); from frame 12 on, each new frame evicts the oldest: 14 evictions
  // (6..19), leaving 20..25 queued. The tracker then skips 20..24 and takes 25.
  source.allow(26);
  ASSERT_TRUE(eventually([&] {
    const PipelineCounters c = p.counters();
    return c.captured == 26 && c.dropped_capture == 14;
  }));
  tracker.release_one();
  ASSERT_EQ(tracker.wait_entered(3), (std::vector<uint64_t>{0, 5, 25}));
  tracker.release_all();
  ASSERT_TRUE(p.wait(30000));
  p.join();

  const PipelineCounters c = p.counters();
  EXPECT_EQ(c.captured, 26u);
  EXPECT_EQ(c.processed, 3u);
  EXPECT_EQ(c.dropped_capture, 14u);
  EXPECT_EQ(c.dropped_tracker, 9u);
  EXPECT_EQ(c.processed + c.dropped_capture + c.dropped_tracker, c.captured);
  EXPECT_EQ(sink.seqs_, (std::vector<uint64_t>{0, 5, 25}));
  EXPECT_EQ(p.status().frames_dropped, 23u);
}

// Free-running source and a slow tracker: whatever the interleaving, the books balance,
// results are strictly increasing and the very last frame is always processed.
TEST(Pipeline, SlowTrackerUnderLoadBalancesTheBooksAndEndsOnTheLastFrame) {
  CountingSource source(3000);
  ScriptedTracker tracker;
  tracker.set_spin_ns(200000);  // 0.2 ms per frame, slower than the source
  IdleMapper mapper;
  RecordingSink sink;
  const ReplayReport rep = replay_source(source, tracker, mapper, small_options(false), {&sink});
  const PipelineStatus& s = rep.status;
  EXPECT_EQ(s.frames_captured, 3000u);
  EXPECT_EQ(s.frames_processed + s.frames_dropped, s.frames_captured);
  EXPECT_EQ(s.frames_dropped, s.dropped_capture + s.dropped_tracker);
  EXPECT_EQ(s.frames_published + s.publish_overflows, s.frames_processed);
  ASSERT_FALSE(rep.frames.empty());
  for (size_t i = 1; i < rep.frames.size(); ++i) {
    ASSERT_GT(rep.frames[i].seq, rep.frames[i - 1].seq);
  }
  EXPECT_EQ(rep.frames.back().seq, 2999u) << "end of stream must not drop the newest frame";
}

// Drop accounting with every kind of drop: frames the source passed over (including after
// its last delivered frame), evicted by capture and skipped by the tracker. Every frame the
// source had is either processed or counted as dropped, exactly once.
TEST(Pipeline, DropAccountingIncludesFramesTheSourceSkipped) {
  SkippingSource source(3000, /*every=*/7, /*skip_tail=*/5);
  ASSERT_EQ(source.skipped_expected(), 427u + 5u);  // frames 6, 13, .., 2988 and the tail
  ScriptedTracker tracker;
  tracker.set_spin_ns(200000);  // slower than the source: capture and tracker drops too
  IdleMapper mapper;
  RecordingSink sink;
  const ReplayReport rep = replay_source(source, tracker, mapper, small_options(false), {&sink});
  const PipelineStatus& s = rep.status;
  EXPECT_EQ(s.source_skipped, source.skipped_expected());
  EXPECT_EQ(s.frames_captured, 3000u - source.skipped_expected());
  EXPECT_EQ(s.frames_dropped, s.source_skipped + s.dropped_capture + s.dropped_tracker);
  EXPECT_EQ(s.frames_processed + s.frames_dropped, 3000u) << "every frame of the source";
  EXPECT_EQ(s.frames_captured + s.source_skipped, s.frames_processed + s.frames_dropped);
  EXPECT_EQ(s.frames_published + s.publish_overflows, s.frames_processed);
  EXPECT_GT(s.dropped_capture + s.dropped_tracker, 0u) << "the tracker is the slower stage";
  EXPECT_EQ(sink.last_status_.frames_dropped, s.frames_dropped) << "final status to sinks";
  ASSERT_FALSE(rep.frames.empty());
  EXPECT_EQ(rep.frames.back().seq, 2994u) << "the last delivered frame is processed";
}

// The real paced replay source whose frames take longer to load than the frame period: it
// falls behind and skips (newest due frame wins); the books still balance.
TEST(Pipeline, PacedReplaySourceThatFallsBehindBalancesTheBooks) {
  class SlowSequence : public RecordedSequence {
   public:
    bool stamp(int64_t index, int64_t& stamp_ns) const override {
      if (index < 0 || index >= 400) return false;
      stamp_ns = index * 1000000;  // 1 kHz
      return true;
    }
    SourceStatus load(int64_t index, cv::Mat& image) override {
      if (index >= 400) return SourceStatus::kEndOfStream;
      image.create(24, 32, CV_8UC1);
      image.setTo(static_cast<int>(index % 256));
      const int64_t until = mono_now_ns() + 2000000;  // 2 ms: slower than the 1 ms period
      while (mono_now_ns() < until) {
      }
      return SourceStatus::kOk;
    }
  };
  SourceInfo info;
  info.uri = "fake:slow";
  info.kind = "fake";
  info.width = 32;
  info.height = 24;
  info.frame_count = 400;
  ReplaySource source(std::make_unique<SlowSequence>(), info, std::nullopt, std::nullopt, 1.0);
  ScriptedTracker tracker;
  IdleMapper mapper;
  const ReplayReport rep = replay_source(source, tracker, mapper, small_options(false));
  const PipelineStatus& s = rep.status;
  EXPECT_GT(s.source_skipped, 0u) << "loading takes twice the frame period";
  EXPECT_EQ(s.source_skipped, source.counters().skipped);
  EXPECT_EQ(s.frames_captured + s.source_skipped, 400u);
  EXPECT_EQ(s.frames_processed + s.frames_dropped, 400u);
  EXPECT_EQ(s.frames_dropped, s.source_skipped + s.dropped_capture + s.dropped_tracker);
}

// Progress output: a bar redrawn in place on a terminal, plain lines every 10% otherwise.
TEST(Pipeline, ProgressPrintsPlainLinesWhenNotATerminal) {
  for (const bool terminal : {false, true}) {
    std::FILE* f = std::tmpfile();
    ASSERT_NE(f, nullptr);
    ProgressSink progress(200, f, terminal);
    FrameResult r;
    for (int i = 0; i < 200; ++i) {
      if (i % 3 == 2) continue;  // dropped frames: the position follows the dataset index
      r.seq = static_cast<uint64_t>(i);
      r.dataset_index = i;
      progress.on_frame(r);
    }
    std::rewind(f);
    std::string text;
    char buf[256];
    size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) text.append(buf, n);
    std::fclose(f);
    const auto count = [&](char c) { return std::count(text.begin(), text.end(), c); };
    if (terminal) {
      EXPECT_GT(count('\r'), 50) << "redrawn in place";
      EXPECT_EQ(count('\n'), 1) << "one newline when done";
      EXPECT_NE(text.find("100% frame 200/200"), std::string::npos) << text;
    } else {
      EXPECT_EQ(count('\r'), 0) << text;
      EXPECT_EQ(count('\n'), 11) << "0%, 10%, ..., 100%: " << text;
      EXPECT_NE(text.find("replay:  50% frame 100/200"), std::string::npos) << text;
      EXPECT_NE(text.find("replay: 100% frame 200/200"), std::string::npos) << text;
    }
  }
}

TEST(Pipeline, StopRequestEndsALiveSourceWithinTwoSeconds) {
  CountingSource camera(-1, 64, 48, 33333333, /*paced=*/true, /*live=*/true);
  ScriptedTracker tracker;
  IdleMapper mapper;
  PipelineOptions o = small_options(false);
  o.params.read_timeout_ms = 100;  // the default
  o.params.mapper_step_timeout_ms = 50;
  Pipeline p(camera, tracker, mapper, o);
  p.start();
  ASSERT_TRUE(eventually([&] { return p.frames_processed() >= 3; }));
  EXPECT_TRUE(p.running());
  p.request_stop();
  EXPECT_TRUE(p.wait(2000)) << "every thread must finish within 2 s of the stop request";
  p.join();
  EXPECT_FALSE(p.running());
  EXPECT_TRUE(p.finished());
  EXPECT_GE(p.counters().processed, 3u);
}

TEST(Pipeline, StopRequestEndsASilentCamera) {
  GatedSource camera(1000000);  // never allowed: every read times out
  ScriptedTracker tracker;
  IdleMapper mapper;
  Pipeline p(camera, tracker, mapper, small_options(false));
  p.start();
  ASSERT_TRUE(eventually([&] { return p.counters().source_timeouts >= 2; }));
  p.request_stop();
  EXPECT_TRUE(p.wait(2000));
  p.join();
  EXPECT_EQ(p.counters().captured, 0u);
  EXPECT_EQ(p.counters().processed, 0u);
}

class GatedSink : public PipelineSink {
 public:
  void on_frame(const FrameResult&) override {
    std::unique_lock<std::mutex> lock(m_);
    ++entered_;
    cv_.notify_all();
    cv_.wait(lock, [&] { return open_; });
    ++frames_;
  }
  void open() {
    {
      std::lock_guard<std::mutex> lock(m_);
      open_ = true;
    }
    cv_.notify_all();
  }
  bool wait_entered() {
    std::unique_lock<std::mutex> lock(m_);
    return cv_.wait_for(lock, std::chrono::seconds(30), [&] { return entered_ > 0; });
  }
  int frames_ = 0;

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool open_ = false;
  int entered_ = 0;
};

// A publisher stuck in the network must not stall the tracker: results that do not fit in
// the output ring are counted, the tracker keeps going.
TEST(Pipeline, StuckPublisherNeverBlocksTheTracker) {
  GatedSource source(20);
  ScriptedTracker tracker;
  IdleMapper mapper;
  GatedSink sink;
  PipelineOptions o = small_options(false);
  o.params.output_ring_capacity = 2;
  Pipeline p(source, tracker, mapper, o);
  p.add_sink(&sink);
  p.start();
  source.allow(1);
  ASSERT_TRUE(sink.wait_entered());  // the publisher now holds frame 0
  for (uint64_t n = 2; n <= 20; ++n) {
    source.allow(n);  // one at a time: the tracker takes each (no drops upstream)
    ASSERT_TRUE(eventually([&] { return p.counters().processed == n; })) << n;
  }
  const PipelineCounters c = p.counters();
  EXPECT_EQ(c.processed, 20u);
  EXPECT_EQ(c.dropped_capture + c.dropped_tracker, 0u);
  EXPECT_EQ(c.publish_overflows, 18u);  // ring of 2 holds frames 0 and 1
  sink.open();
  ASSERT_TRUE(p.wait(30000));
  p.join();
  EXPECT_EQ(sink.frames_, 2);
  EXPECT_EQ(p.counters().published, 2u);
}

TEST(Pipeline, ThreadsAreNamedAndPinnedAsConfigured) {
  CountingSource source(50);
  ScriptedTracker tracker;
  IdleMapper mapper;
  PipelineOptions o = small_options(true);
  o.threads.tracker.cores = {0};
  Pipeline p(source, tracker, mapper, o);
  p.start();
  ASSERT_TRUE(p.wait(30000));
  p.join();
  EXPECT_EQ(source.reader_name(), "rdslam-capture");
  EXPECT_EQ(tracker.thread_name_seen(), "rdslam-tracker");
  EXPECT_EQ(mapper.thread_name_seen(), "rdslam-mapper");
}

class AffinityProbe : public TrackerStage {
 public:
  TrackResult track(const Frame&) override {
    cpu_set_t set;
    CPU_ZERO(&set);
    pthread_getaffinity_np(pthread_self(), sizeof(set), &set);
    only_core0_ = CPU_COUNT(&set) == 1 && CPU_ISSET(0, &set);
    policy_ = sched_getscheduler(0);
    return TrackResult{};
  }
  bool only_core0_ = false;
  int policy_ = -1;
};

TEST(Pipeline, TrackerAffinityAndPriorityAreApplied) {
  CountingSource source(5);
  AffinityProbe tracker;
  IdleMapper mapper;
  PipelineOptions o = small_options(false);  // real-time policy: priorities apply
  o.threads.tracker.cores = {0};
  o.threads.tracker.priority = 10;  // SCHED_FIFO if permitted, otherwise a warning
  replay_source(source, tracker, mapper, o);
  EXPECT_TRUE(tracker.only_core0_);
  // Either FIFO was granted or the thread fell back to normal scheduling; never anything else.
  EXPECT_TRUE(tracker.policy_ == SCHED_FIFO || tracker.policy_ == SCHED_OTHER) << tracker.policy_;
  const bool fifo_permitted = [] {
    sched_param sp{};
    sp.sched_priority = 10;
    pthread_attr_t a;
    pthread_attr_init(&a);
    pthread_attr_setinheritsched(&a, PTHREAD_EXPLICIT_SCHED);
    pthread_attr_setschedpolicy(&a, SCHED_FIFO);
    pthread_attr_setschedparam(&a, &sp);
    pthread_t t;
    const int rc = pthread_create(
        &t, &a, [](void*) -> void* { return nullptr; }, nullptr);
    pthread_attr_destroy(&a);
    if (rc == 0) pthread_join(t, nullptr);
    return rc == 0;
  }();
  if (fifo_permitted) {
    EXPECT_EQ(tracker.policy_, SCHED_FIFO) << "permitted here, so applied";
  }

  // A lossless replay never runs at SCHED_FIFO: it would hold its cores for the whole run.
  CountingSource source2(5);
  AffinityProbe tracker2;
  o.lossless = true;
  replay_source(source2, tracker2, mapper, o);
  EXPECT_TRUE(tracker2.only_core0_);
  EXPECT_EQ(tracker2.policy_, SCHED_OTHER);
}

// Raising a thread's nice value is always permitted: the mapper runs at the configured
// nice, the other threads keep the process's.
class NiceProbeMapper : public MapperStage {
 public:
  bool step(int timeout_ms) override {
    errno = 0;
    nice_ = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
    std::this_thread::sleep_for(std::chrono::milliseconds(std::min(timeout_ms, 5)));
    return false;
  }
  std::atomic<int> nice_{-100};
};

TEST(Pipeline, MapperNiceIsApplied) {
  CountingSource source(5);
  ScriptedTracker tracker;
  NiceProbeMapper mapper;
  PipelineOptions o = small_options(true);
  const int base = getpriority(PRIO_PROCESS, 0);
  o.threads.mapper.nice = std::min(base + 7, 19);
  replay_source(source, tracker, mapper, o);
  EXPECT_EQ(mapper.nice_.load(), std::min(base + 7, 19));
  EXPECT_EQ(getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid))), base)
      << "only the mapper thread changed";
}

TEST(Pipeline, PeriodicStatusIsPublishedAndFinalStatusSummarisesTheRun) {
  CountingSource source(30, 64, 48, 10000000, /*paced=*/true);  // 100 fps for 0.3 s
  ScriptedTracker tracker;
  IdleMapper mapper;
  RecordingSink sink;
  PipelineOptions o = small_options(false);
  o.params.stats_period_ms = 100;
  replay_source(source, tracker, mapper, o, {&sink});
  EXPECT_GE(sink.statuses_, 2) << "at least one periodic report and the final one";
  EXPECT_FALSE(sink.last_status_.running);
  EXPECT_TRUE(sink.last_status_.end_of_stream);
  EXPECT_EQ(sink.last_status_.frames_captured, 30u);
  EXPECT_EQ(sink.last_status_.frames_processed + sink.last_status_.frames_dropped, 30u);
  EXPECT_GT(sink.last_status_.cpu_s[kTrackerThread] + sink.last_status_.cpu_s[kCaptureThread], 0.0);
}

TEST(Pipeline, RejectsTooFewSlots) {
  CountingSource source(1);
  ScriptedTracker tracker;
  IdleMapper mapper;
  PipelineOptions o;
  o.params.pool_slots = 2;
  EXPECT_THROW(Pipeline(source, tracker, mapper, o), std::invalid_argument);
}

// ---- pass-through stages ----

Trajectory line_trajectory(int n, int64_t period_ns) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    StampedPose p;
    p.stamp_ns = i * period_ns;
    p.p_world_cam = Eigen::Vector3d(i, 2.0 * i, -i);
    p.q_world_cam = Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * i, Eigen::Vector3d::UnitZ()));
    t.push_back(p);
  }
  return t;
}

TEST(PassthroughStages, TrackerReportsGroundTruthByNearestStamp) {
  PassthroughStages stages(line_trajectory(10, 100000000));
  Frame f;
  f.stamp_ns = 300000000 + 2000000;  // 2 ms after pose 3
  TrackResult r = stages.tracker().track(f);
  EXPECT_EQ(r.state, TrackingState::kTracking);
  EXPECT_EQ(r.p_world_cam, Eigen::Vector3d(3, 6, -3));
  EXPECT_NEAR(r.q_world_cam.angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitZ()))),
              0.0, 1e-12);
  EXPECT_EQ(r.covariance[0], -1.0) << "pass-through poses carry no covariance";
  f.stamp_ns = 350000000;  // 50 ms from any pose
  r = stages.tracker().track(f);
  EXPECT_EQ(r.state, TrackingState::kInitializing);
  EXPECT_EQ(r.p_world_cam, Eigen::Vector3d::Zero());
}

TEST(PassthroughStages, WithoutGroundTruthEveryFrameIsInitializing) {
  PassthroughStages stages(std::nullopt);
  Frame f;
  EXPECT_EQ(stages.tracker().track(f).state, TrackingState::kInitializing);
  EXPECT_FALSE(stages.mapper().step(1));
}

TEST(PassthroughStages, MapperStoresEveryTenthFrameAndFinishesAtEndOfStream) {
  CountingSource source(95, 64, 48, 50000000);
  PassthroughStages stages(line_trajectory(95, 50000000));
  const ReplayReport rep =
      replay_source(source, stages.tracker(), stages.mapper(), small_options(true));
  ASSERT_EQ(rep.frames.size(), 95u);
  for (const FrameResult& fr : rep.frames) {
    ASSERT_EQ(fr.result.state, TrackingState::kTracking);
    ASSERT_EQ(fr.result.p_world_cam.x(), static_cast<double>(fr.seq));
  }
  // Keyframes at frames 0, 10, ..., 90; the mapper drains them before it exits.
  EXPECT_EQ(stages.keyframes(), 10);
  EXPECT_EQ(stages.keyframes_dropped(), 0u);
  EXPECT_EQ(rep.stages.mapper.total, 10u);
}

// threads.opencv_threads: -1 sizes OpenCV's pool by the cores the pipeline threads may use.
TEST(OpenCvThreads, AutoCountsTheUnionOfTheConfiguredCoresInTheProcessMask) {
  cpu_set_t mask;
  CPU_ZERO(&mask);
  ASSERT_EQ(sched_getaffinity(0, sizeof(mask), &mask), 0);
  std::vector<int> allowed;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &mask)) allowed.push_back(c);
  }
  ThreadParams t;  // every thread on any core
  EXPECT_EQ(opencv_threads_for(t), static_cast<int>(allowed.size()));
  for (ThreadSpec* s : {&t.capture, &t.tracker, &t.mapper, &t.publisher}) s->cores = {allowed[0]};
  EXPECT_EQ(opencv_threads_for(t), 1);
  t.mapper.cores = {allowed[0], 100000};  // a core this process cannot use does not count
  EXPECT_EQ(opencv_threads_for(t), 1);
  if (allowed.size() >= 2) {
    t.tracker.cores = {allowed[1]};
    EXPECT_EQ(opencv_threads_for(t), 2);
  }
  t.publisher.cores.clear();  // one thread may run anywhere: the whole mask
  EXPECT_EQ(opencv_threads_for(t), static_cast<int>(allowed.size()));
  for (int n : {0, 1, 3}) {
    t.opencv_threads = n;  // explicit values are taken as they are
    EXPECT_EQ(opencv_threads_for(t), n);
  }
}

TEST(OpenCvThreads, PipelineStartAppliesTheConfiguredPoolSize) {
  const int before = cv::getNumThreads();
  for (int n : {1, 3}) {
    CountingSource source(5);
    ScriptedTracker tracker;
    IdleMapper mapper;
    PipelineOptions o = small_options(true);
    o.threads.opencv_threads = n;
    replay_source(source, tracker, mapper, o);
    EXPECT_EQ(cv::getNumThreads(), n);
  }
  cv::setNumThreads(before);
}

}  // namespace
}  // namespace rdslam
