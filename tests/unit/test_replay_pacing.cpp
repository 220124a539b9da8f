// Replay pacing (drivers/replay_source.h) on a simulated CLOCK_MONOTONIC: deterministic,
// so a slow consumer's "newest frame wins" and the skipped count are exact. The real-time
// schedule error is measured by benchmarks/bench_replay_pacing.cpp, not here.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "drivers/replay_source.h"

using namespace rdslam;

namespace {

constexpr int64_t kMs = 1000000;
constexpr int64_t kPeriod = 33 * kMs + 333333;  // 30 fps
constexpr int64_t kStamp0 = 1403715273262142976LL;

class FakeClock : public MonoClock {
 public:
  int64_t now_ns() override { return now; }
  void sleep_until_ns(int64_t deadline_ns) override {
    sleeps.push_back(deadline_ns);
    if (deadline_ns > now) now = deadline_ns;
  }
  int64_t now = 5000 * kMs;
  std::vector<int64_t> sleeps;
};

// Frame i is a 8x4 grey image filled with value i; loading advances the clock by
// `decode_ns` (decoding takes time); frame `bad` is unreadable.
class CountingSequence : public RecordedSequence {
 public:
  CountingSequence(int n, FakeClock& clock, int64_t decode_ns = 0, int bad = -1)
      : n_(n), clock_(clock), decode_ns_(decode_ns), bad_(bad) {}
  bool stamp(int64_t i, int64_t& s) const override {
    if (i < 0 || i >= n_) return false;
    s = kStamp0 + i * kPeriod;
    return true;
  }
  SourceStatus load(int64_t i, cv::Mat& image) override {
    if (i >= n_) return SourceStatus::kEndOfStream;
    loaded.push_back(i);
    clock_.now += decode_ns_;
    if (i == bad_) return SourceStatus::kFault;
    image.create(4, 8, CV_8UC1);
    image.setTo(static_cast<int>(i));
    return SourceStatus::kOk;
  }
  std::vector<int64_t> loaded;

 private:
  int n_;
  FakeClock& clock_;
  int64_t decode_ns_;
  int bad_;
};

struct Rig {
  explicit Rig(double speed, int n = 30, int64_t decode_ns = 0, int bad = -1) {
    auto s = std::make_unique<CountingSequence>(n, clock, decode_ns, bad);
    seq = s.get();
    SourceInfo info;
    info.kind = "test";
    info.width = 8;
    info.height = 4;
    info.format = PixelFormat::kGray8;
    info.frame_count = n;
    src = std::make_unique<ReplaySource>(std::move(s), info, std::nullopt, std::nullopt, speed,
                                         clock);
    frame.image.create(4, 8, CV_8UC1);
  }
  FakeClock clock;
  CountingSequence* seq = nullptr;
  std::unique_ptr<ReplaySource> src;
  Frame frame;
};

}  // namespace

TEST(ReplayPacing, SpeedZeroDeliversEveryFrameInOrderWithoutSleeping) {
  Rig r(0.0, 5);
  EXPECT_FALSE(r.src->info().live);
  for (int i = 0; i < 5; ++i) {
    ASSERT_EQ(r.src->read(r.frame, 0), SourceStatus::kOk);
    EXPECT_EQ(r.frame.dataset_index, i);
    EXPECT_EQ(r.frame.seq, static_cast<uint64_t>(i));
    EXPECT_EQ(r.frame.stamp_ns, kStamp0 + i * kPeriod);
    EXPECT_EQ(r.frame.image.at<uint8_t>(0, 0), i);
  }
  EXPECT_EQ(r.src->read(r.frame, 0), SourceStatus::kEndOfStream);
  EXPECT_EQ(r.src->read(r.frame, 0), SourceStatus::kEndOfStream);  // and stays there
  EXPECT_TRUE(r.clock.sleeps.empty());
  EXPECT_EQ(r.src->counters().delivered, 5u);
  EXPECT_EQ(r.src->counters().skipped, 0u);
}

TEST(ReplayPacing, ConsumerThatKeepsUpGetsEveryFrameAtItsDueTime) {
  Rig r(1.0, 10);
  EXPECT_TRUE(r.src->info().live);  // paced replay is handled like a camera
  const int64_t t0 = r.clock.now;
  for (int i = 0; i < 10; ++i) {
    ASSERT_EQ(r.src->read(r.frame, 1000), SourceStatus::kOk);
    EXPECT_EQ(r.frame.dataset_index, i);
    EXPECT_EQ(r.frame.stamp_ns, kStamp0 + i * kPeriod);
    // Delivered exactly at t0 + (stamp_i - stamp_0) / speed, on the absolute deadline.
    EXPECT_EQ(r.clock.now, t0 + i * kPeriod);
    EXPECT_EQ(r.frame.arrival_mono_ns, t0 + i * kPeriod);
    r.clock.now += 5 * kMs;  // processing well within the period
  }
  EXPECT_EQ(r.src->counters().skipped, 0u);
  EXPECT_EQ(r.src->read(r.frame, 1000), SourceStatus::kEndOfStream);
}

TEST(ReplayPacing, SlowConsumerGetsTheNewestDueFrameAndSkippedAreCounted) {
  Rig r(1.0, 30);
  const int64_t t0 = r.clock.now;
  ASSERT_EQ(r.src->read(r.frame, 1000), SourceStatus::kOk);
  EXPECT_EQ(r.frame.dataset_index, 0);
  // The consumer needs 3.5 frame periods per frame: at each read, frames up to
  // floor(elapsed / period) are due; the newest of them must be delivered.
  int64_t expected_skipped = 0;
  int64_t last = 0;
  std::vector<int64_t> delivered{0};
  for (;;) {
    r.clock.now += kPeriod * 7 / 2;
    const int64_t due_newest = (r.clock.now - t0) / kPeriod;
    const SourceStatus st = r.src->read(r.frame, 1000);
    if (st == SourceStatus::kEndOfStream) break;
    ASSERT_EQ(st, SourceStatus::kOk);
    const int64_t expect = std::min<int64_t>(due_newest, 29);
    EXPECT_EQ(r.frame.dataset_index, expect);
    EXPECT_EQ(r.frame.image.at<uint8_t>(0, 0), expect);
    EXPECT_EQ(r.frame.seq, static_cast<uint64_t>(expect));      // the gap in seq shows the skip
    EXPECT_EQ(r.frame.arrival_mono_ns, t0 + expect * kPeriod);  // when it was due
    expected_skipped += expect - last - 1;
    last = expect;
    delivered.push_back(expect);
    EXPECT_EQ(r.src->counters().skipped, static_cast<uint64_t>(expected_skipped));
  }
  EXPECT_EQ(last, 29);
  EXPECT_GT(expected_skipped, 15);
  EXPECT_EQ(r.src->counters().delivered + r.src->counters().skipped, 30u);
  // Skipped frames were never decoded.
  EXPECT_EQ(r.seq->loaded, delivered);
}

TEST(ReplayPacing, DecodeHappensBeforeTheDeadlineNotAfterIt) {
  // Decoding takes 10 ms of a 33 ms period: the frame is still delivered on time.
  Rig r(1.0, 5, 10 * kMs);
  const int64_t t0 = r.clock.now;
  ASSERT_EQ(r.src->read(r.frame, 1000), SourceStatus::kOk);
  // The schedule starts once frame 0 is decoded: it is not late by its decoding time.
  const int64_t first_due = r.frame.arrival_mono_ns;
  EXPECT_EQ(first_due, t0 + 10 * kMs);
  EXPECT_EQ(r.clock.now, first_due);
  r.clock.now += 1 * kMs;
  ASSERT_EQ(r.src->read(r.frame, 1000), SourceStatus::kOk);
  EXPECT_EQ(r.frame.dataset_index, 1);
  EXPECT_EQ(r.clock.now, first_due + kPeriod);
  EXPECT_EQ(r.src->counters().skipped, 0u);
}

TEST(ReplayPacing, SpeedScalesTheSchedule) {
  Rig r(2.0, 5);
  const int64_t t0 = r.clock.now;
  for (int i = 0; i < 5; ++i) {
    ASSERT_EQ(r.src->read(r.frame, 1000), SourceStatus::kOk);
    EXPECT_NEAR(static_cast<double>(r.clock.now - t0), i * kPeriod / 2.0, 1.0);
  }
  Rig slow(0.5, 3);
  const int64_t s0 = slow.clock.now;
  for (int i = 0; i < 3; ++i) ASSERT_EQ(slow.src->read(slow.frame, 1000), SourceStatus::kOk);
  EXPECT_EQ(slow.clock.now - s0, 4 * kPeriod);
}

// `rdslam replay --realtime --speed 3`: frames come three times as often, with their recorded
// stamps; a consumer that needs one recorded period per frame gets every third frame.
TEST(ReplayPacing, FasterThanRecordedKeepsStampsAndSkipsWhatTheConsumerCannotTake) {
  Rig r(3.0, 30);
  const int64_t t0 = r.clock.now;
  std::vector<int64_t> delivered;
  for (;;) {
    const SourceStatus st = r.src->read(r.frame, 1000);
    if (st == SourceStatus::kEndOfStream) break;
    ASSERT_EQ(st, SourceStatus::kOk);
    const int64_t i = r.frame.dataset_index;
    delivered.push_back(i);
    EXPECT_EQ(r.frame.stamp_ns, kStamp0 + i * kPeriod) << "stamps stay the recorded ones";
    EXPECT_EQ(r.frame.arrival_mono_ns, t0 + i * (kPeriod / 3)) << "due at 3x the rate";
    r.clock.now += kPeriod;  // one recorded period of work: three frames fall due meanwhile
  }
  EXPECT_EQ(delivered, (std::vector<int64_t>{0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 29}));
  EXPECT_EQ(r.src->counters().skipped, 19u);
  EXPECT_EQ(r.seq->loaded, delivered);  // skipped frames were never decoded
}

TEST(ReplayPacing, TimeoutKeepsTheStagedFrameForTheNextRead) {
  Rig r(0.1, 3);  // 10x slower: frame 1 is due 333 ms after frame 0
  const int64_t t0 = r.clock.now;
  ASSERT_EQ(r.src->read(r.frame, 50), SourceStatus::kOk);
  const int64_t call = r.clock.now;
  EXPECT_EQ(r.src->read(r.frame, 50), SourceStatus::kTimeout);
  EXPECT_EQ(r.clock.now, call + 50 * kMs);  // blocked exactly the timeout
  EXPECT_EQ(r.src->counters().timeouts, 1u);
  ASSERT_EQ(r.src->read(r.frame, 1000), SourceStatus::kOk);
  EXPECT_EQ(r.frame.dataset_index, 1);
  EXPECT_EQ(r.clock.now, t0 + kPeriod * 10);
  EXPECT_EQ(r.seq->loaded, (std::vector<int64_t>{0, 1}));  // decoded once, not per call
}

TEST(ReplayPacing, UnreadableFrameIsCountedAndSkipped) {
  for (double speed : {0.0, 1.0}) {
    Rig r(speed, 4, 0, /*bad=*/1);
    std::vector<int64_t> got;
    int faults = 0;
    for (;;) {
      const SourceStatus st = r.src->read(r.frame, 1000);
      if (st == SourceStatus::kEndOfStream) break;
      if (st == SourceStatus::kFault) {
        ++faults;
        continue;
      }
      ASSERT_EQ(st, SourceStatus::kOk);
      got.push_back(r.frame.dataset_index);
    }
    EXPECT_EQ(got, (std::vector<int64_t>{0, 2, 3})) << "speed " << speed;
    EXPECT_EQ(faults, 1);
    EXPECT_EQ(r.src->counters().faults, 1u);
  }
}

TEST(ReplayPacing, SystemClockSleepsUntilAnAbsoluteDeadline) {
  MonoClock& c = system_mono_clock();
  const int64_t start = c.now_ns();
  c.sleep_until_ns(start + 3 * kMs);
  EXPECT_GE(c.now_ns(), start + 3 * kMs);
  const int64_t before = c.now_ns();
  c.sleep_until_ns(before - 1000 * kMs);  // a past deadline returns at once
  EXPECT_LT(c.now_ns() - before, 1000 * kMs);
}
