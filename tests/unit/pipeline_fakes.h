// Test doubles for the pipeline tests: frame sources and stages that are controlled by the
// test (no dependency on the dataset readers) and never allocate per frame.
#pragma once

#include <pthread.h>
#include <time.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/frame_source.h"
#include "core/stages.h"
#include "firmware_app/pipeline.h"

namespace rdslam {
namespace testing_fakes {

inline std::string thread_name() {
  char buf[32] = {0};
  pthread_getname_np(pthread_self(), buf, sizeof(buf));
  return buf;
}

// Frames 0..count-1 (count < 0: endless) of w x h gray; stamps seq * period_ns. With
// `paced`, read() returns each frame at start + seq * period (like a camera or a real-time
// replay) and kTimeout when that is further away than the read timeout.
class CountingSource : public FrameSource {
 public:
  CountingSource(int64_t count, int w = 64, int h = 48, int64_t period_ns = 33333333,
                 bool paced = false, bool live = false)
      : count_(count), period_ns_(period_ns), paced_(paced) {
    info_.uri = "fake:counting";
    info_.kind = "fake";
    info_.width = w;
    info_.height = h;
    info_.nominal_fps = 1e9 / static_cast<double>(period_ns);
    info_.live = live;
    info_.frame_count = count;
  }
  SourceStatus read(Frame& out, int timeout_ms) override {
    if (count_ >= 0 && next_ >= static_cast<uint64_t>(count_)) return SourceStatus::kEndOfStream;
    if (reader_name_.empty()) reader_name_ = thread_name();  // first call only
    if (paced_) {
      if (start_ns_ == 0) start_ns_ = mono_now_ns();
      const int64_t due = start_ns_ + static_cast<int64_t>(next_) * period_ns_;
      const int64_t now = mono_now_ns();
      if (due - now > static_cast<int64_t>(timeout_ms) * 1000000LL) {
        sleep_until(now + static_cast<int64_t>(timeout_ms) * 1000000LL);
        return SourceStatus::kTimeout;
      }
      sleep_until(due);
    }
    out.image.data[0] = static_cast<uint8_t>(next_);
    out.seq = next_;
    out.stamp_ns = static_cast<int64_t>(next_) * period_ns_;
    out.dataset_index = static_cast<int64_t>(next_);
    ++next_;
    return SourceStatus::kOk;
  }
  const SourceInfo& info() const override { return info_; }
  // Name of the thread that called read() (valid after the first frame).
  const std::string& reader_name() const { return reader_name_; }

 private:
  static void sleep_until(int64_t mono_ns) {
    timespec ts{static_cast<time_t>(mono_ns / 1000000000LL),
                static_cast<long>(mono_ns % 1000000000LL)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
    }
  }
  SourceInfo info_;
  int64_t count_;
  int64_t period_ns_;
  bool paced_;
  uint64_t next_ = 0;
  int64_t start_ns_ = 0;
  std::string reader_name_;
};

// Frames 0..count-1, unpaced; passes over (never delivers) every frame i with
// i % every == every - 1 and the last `skip_tail` frames, counting them in
// SourceCounters::skipped like a paced replay that fell behind. Exactly
// skipped_expected() frames are skipped.
class SkippingSource : public FrameSource {
 public:
  SkippingSource(uint64_t count, uint64_t every, uint64_t skip_tail)
      : count_(count), every_(every), tail_(skip_tail) {
    info_.uri = "fake:skipping";
    info_.kind = "fake";
    info_.width = 32;
    info_.height = 24;
    info_.live = true;
    info_.frame_count = static_cast<int64_t>(count);
  }
  uint64_t skipped_expected() const {
    uint64_t n = tail_;
    for (uint64_t i = 0; i + tail_ < count_; ++i) n += skipped(i) ? 1 : 0;
    return n;
  }
  SourceStatus read(Frame& out, int /*timeout_ms*/) override {
    while (next_ + tail_ < count_ && skipped(next_)) {
      ++next_;
      ++counters_.skipped;
    }
    if (next_ + tail_ >= count_) {
      counters_.skipped += count_ - next_;  // the tail: passed over at the very end
      next_ = count_;
      return SourceStatus::kEndOfStream;
    }
    out.seq = next_;
    out.stamp_ns = static_cast<int64_t>(next_) * 1000000;
    out.dataset_index = static_cast<int64_t>(next_);
    ++next_;
    ++counters_.delivered;
    return SourceStatus::kOk;
  }
  const SourceInfo& info() const override { return info_; }
  SourceCounters counters() const override { return counters_; }

 private:
  bool skipped(uint64_t i) const { return every_ > 0 && i % every_ == every_ - 1; }
  SourceInfo info_;
  uint64_t count_, every_, tail_;
  uint64_t next_ = 0;
  SourceCounters counters_;
};

// Delivers frame n only after the test called allow(n + 1); ends after `count` frames.
class GatedSource : public FrameSource {
 public:
  explicit GatedSource(uint64_t count) : count_(count) {
    info_.uri = "fake:gated";
    info_.kind = "fake";
    info_.width = 32;
    info_.height = 24;
    info_.frame_count = static_cast<int64_t>(count);
  }
  void allow(uint64_t frames) {
    {
      std::lock_guard<std::mutex> lock(m_);
      allowed_ = frames;
    }
    cv_.notify_all();
  }
  SourceStatus read(Frame& out, int timeout_ms) override {
    if (next_ >= count_) return SourceStatus::kEndOfStream;
    std::unique_lock<std::mutex> lock(m_);
    if (!cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                      [&] { return allowed_ > next_; })) {
      return SourceStatus::kTimeout;
    }
    out.seq = next_;
    out.stamp_ns = static_cast<int64_t>(next_) * 1000000;
    ++next_;
    return SourceStatus::kOk;
  }
  const SourceInfo& info() const override { return info_; }

 private:
  SourceInfo info_;
  uint64_t count_;
  uint64_t next_ = 0;
  uint64_t allowed_ = 0;
  std::mutex m_;
  std::condition_variable cv_;
};

// Reports pose x = seq; optionally blocks in track() until the test releases each frame.
class ScriptedTracker : public TrackerStage {
 public:
  explicit ScriptedTracker(bool gated = false, size_t max_frames = 100000) : gated_(gated) {
    seen_.reserve(max_frames);
  }
  TrackResult track(const Frame& f) override {
    if (name_.empty()) name_ = thread_name();
    {
      std::unique_lock<std::mutex> lock(m_);
      if (seen_.size() < seen_.capacity()) seen_.push_back(f.seq);
      cv_.notify_all();
      if (gated_) cv_.wait(lock, [&] { return released_ >= seen_.size(); });
    }
    if (spin_ns_ > 0) {
      const int64_t until = mono_now_ns() + spin_ns_;
      while (mono_now_ns() < until) {
      }
    }
    TrackResult r;
    r.state = TrackingState::kTracking;
    r.p_world_cam.x() = static_cast<double>(f.seq);
    r.inliers = static_cast<int>(f.seq % 1000);
    return r;
  }
  // Test thread: wait until track() has been entered `n` times; returns the seqs seen.
  std::vector<uint64_t> wait_entered(size_t n) {
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait_for(lock, std::chrono::seconds(30), [&] { return seen_.size() >= n; });
    return seen_;
  }
  void release_one() {
    {
      std::lock_guard<std::mutex> lock(m_);
      ++released_;
    }
    cv_.notify_all();
  }
  void release_all() {
    {
      std::lock_guard<std::mutex> lock(m_);
      gated_ = false;
      released_ = 1u << 30;
    }
    cv_.notify_all();
  }
  void set_spin_ns(int64_t ns) { spin_ns_ = ns; }
  std::vector<uint64_t> seen() {
    std::lock_guard<std::mutex> lock(m_);
    return seen_;
  }
  const std::string& thread_name_seen() const { return name_; }

 private:
  bool gated_;
  size_t released_ = 0;
  int64_t spin_ns_ = 0;
  std::vector<uint64_t> seen_;
  std::mutex m_;
  std::condition_variable cv_;
  std::string name_;
};

// Mapper that waits its timeout on a condition nobody signals, counting steps.
class IdleMapper : public MapperStage {
 public:
  bool step(int timeout_ms) override {
    if (name_.empty()) name_ = thread_name();
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms));
    steps_.fetch_add(1);
    return false;
  }
  uint64_t steps() const { return steps_.load(); }
  const std::string& thread_name_seen() const { return name_; }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::atomic<uint64_t> steps_{0};
  std::string name_;
};

// Records what the publisher thread hands to sinks (preallocated).
class RecordingSink : public PipelineSink {
 public:
  explicit RecordingSink(size_t max_frames = 100000) { seqs_.reserve(max_frames); }
  void on_frame(const FrameResult& r) override {
    if (seqs_.size() < seqs_.capacity()) seqs_.push_back(r.seq);
    pose_matches_seq_ = pose_matches_seq_ && r.result.p_world_cam.x() == static_cast<double>(r.seq);
    latency_ok_ = latency_ok_ && r.publish_mono_ns >= r.tracked_mono_ns &&
                  r.tracked_mono_ns >= r.arrival_mono_ns && r.arrival_mono_ns > 0;
  }
  void on_status(const PipelineStatus& s) override {
    ++statuses_;
    last_status_ = s;
  }
  std::vector<uint64_t> seqs_;
  bool pose_matches_seq_ = true;
  bool latency_ok_ = true;
  int statuses_ = 0;
  PipelineStatus last_status_;
};

// Polls `cond` (a counter condition) for up to 30 s; returns its final value. Tests assert
// the condition, never the time it took.
template <typename F>
bool eventually(F cond) {
  for (int i = 0; i < 30000; ++i) {
    if (cond()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return cond();
}

}  // namespace testing_fakes
}  // namespace rdslam
