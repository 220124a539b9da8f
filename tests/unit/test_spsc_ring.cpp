// Rings, doorbell and latency histogram (core/spsc_ring.h, core/latency_histogram.h).
// The two-thread stress tests are what .ci/run also runs under ThreadSanitizer.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <thread>
#include <vector>

#include "core/latency_histogram.h"
#include "core/spsc_ring.h"

namespace rdslam {
namespace {

TEST(SpscRing, CapacityIsRoundedUpToAPowerOfTwo) {
  EXPECT_EQ(SpscRing<int>(1).capacity(), 2u);
  EXPECT_EQ(SpscRing<int>(5).capacity(), 8u);
  EXPECT_EQ(SpscRing<int>(64).capacity(), 64u);
  EXPECT_EQ(next_pow2(1), 1u);
  EXPECT_EQ(next_pow2(3), 4u);
  EXPECT_EQ(next_pow2(0x80000001u), 0u);
}

TEST(SpscRing, FifoOrderFullAndEmpty) {
  SpscRing<int> r(4);
  int v = -1;
  EXPECT_FALSE(r.try_pop(v));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(r.try_push(i));
  EXPECT_FALSE(r.try_push(99)) << "a full ring must refuse, not overwrite";
  EXPECT_EQ(r.size_approx(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(r.try_pop(v));
  // Wrap around several times.
  for (int i = 0; i < 37; ++i) {
    ASSERT_TRUE(r.try_push(i));
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i);
  }
}

TEST(SpscRing, InPlaceBackCommitFrontPop) {
  SpscRing<std::vector<int>> r(2);
  std::vector<int>* b = r.back();
  ASSERT_NE(b, nullptr);
  b->assign({1, 2, 3});
  EXPECT_EQ(r.front(), nullptr) << "not visible before commit()";
  r.commit();
  std::vector<int>* f = r.front();
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->size(), 3u);
  r.pop();
  EXPECT_EQ(r.front(), nullptr);
}

TEST(SlotRing, EvictOldestTakesTheOldestAndNeverTheEndOfStream) {
  SlotRing r(4);
  uint32_t v = 0;
  EXPECT_FALSE(r.evict_oldest(v));
  ASSERT_TRUE(r.try_push(10));
  ASSERT_TRUE(r.try_push(11));
  ASSERT_TRUE(r.try_push(12));
  ASSERT_TRUE(r.evict_oldest(v));
  EXPECT_EQ(v, 10u);
  ASSERT_TRUE(r.try_pop(v));
  EXPECT_EQ(v, 11u);
  ASSERT_TRUE(r.try_push(SlotRing::kEndOfStream));
  ASSERT_TRUE(r.evict_oldest(v));
  EXPECT_EQ(v, 12u);
  EXPECT_FALSE(r.evict_oldest(v)) << "end of stream must never be dropped";
  ASSERT_TRUE(r.try_pop(v));
  EXPECT_EQ(v, SlotRing::kEndOfStream);
}

TEST(SlotRing, RefusesPushWhenFull) {
  SlotRing r(2);
  EXPECT_TRUE(r.try_push(1));
  EXPECT_TRUE(r.try_push(2));
  EXPECT_FALSE(r.try_push(3));
}

// Two threads, plain SPSC: every element arrives once, in order, with its payload intact.
TEST(SpscRingStress, TwoThreadsInOrderNoLossNoDuplicates) {
  struct Msg {
    uint64_t seq;
    uint64_t check;
  };
  constexpr uint64_t kCount = 200000;
  SpscRing<Msg> ring(64);
  Doorbell bell;
  std::thread producer([&] {
    for (uint64_t i = 0; i < kCount; ++i) {
      while (!ring.try_push(Msg{i, ~i})) std::this_thread::yield();
      bell.ring();
    }
  });
  uint64_t expect = 0;
  bool ok = true;
  while (expect < kCount) {
    const uint32_t t = bell.ticket();
    Msg* m = ring.front();
    if (!m) {
      bell.wait(t, 100);
      continue;
    }
    ok = ok && m->seq == expect && m->check == ~expect;
    ring.pop();
    ++expect;
  }
  producer.join();
  EXPECT_TRUE(ok);
  EXPECT_EQ(expect, kCount);
}

// Two threads on a SlotRing where the producer evicts the oldest entry whenever the ring is
// full (the capture thread's "newest frame wins"). Every pushed value is taken by exactly
// one side, the consumer sees strictly increasing values, nothing is invented.
TEST(SlotRingStress, ProducerEvictionAndConsumerTakeEachEntryExactlyOnce) {
  constexpr uint32_t kCount = 200000;
  SlotRing ring(8);
  Doorbell bell;
  std::vector<uint8_t> taken(kCount, 0);  // written by the consumer only
  std::vector<uint32_t> evicted;          // producer only
  evicted.reserve(kCount);
  std::thread producer([&] {
    for (uint32_t i = 0; i < kCount; ++i) {
      uint32_t old = 0;
      while (!ring.try_push(i)) {
        if (ring.evict_oldest(old)) evicted.push_back(old);
      }
      bell.ring();
    }
    while (!ring.try_push(SlotRing::kEndOfStream)) {
      uint32_t old = 0;
      if (ring.evict_oldest(old)) evicted.push_back(old);
    }
    bell.ring();
  });
  uint64_t popped = 0;
  int64_t last = -1;
  bool increasing = true;
  bool in_range = true;
  for (;;) {
    const uint32_t t = bell.ticket();
    uint32_t v = 0;
    if (!ring.try_pop(v)) {
      bell.wait(t, 100);
      continue;
    }
    if (v == SlotRing::kEndOfStream) break;
    in_range = in_range && v < kCount;
    if (v < kCount) taken[v] += 1;
    increasing = increasing && static_cast<int64_t>(v) > last;
    last = v;
    ++popped;
  }
  producer.join();
  EXPECT_TRUE(in_range);
  EXPECT_TRUE(increasing);
  for (uint32_t e : evicted) {
    ASSERT_LT(e, kCount);
    taken[e] += 1;
  }
  uint64_t exactly_once = 0;
  for (uint8_t n : taken) exactly_once += n == 1;
  EXPECT_EQ(exactly_once, kCount) << "popped " << popped << " evicted " << evicted.size();
  EXPECT_EQ(popped + evicted.size(), kCount);
}

TEST(Doorbell, WaitReturnsAtOnceWhenRungAfterTheTicket) {
  Doorbell bell;
  const uint32_t t = bell.ticket();
  bell.ring();
  const auto t0 = std::chrono::steady_clock::now();
  bell.wait(t, 60000);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30))
      << "a ring before the wait must not be lost";
}

TEST(Doorbell, RingWakesASleepingWaiter) {
  Doorbell bell;
  std::atomic<bool> woke{false};
  const uint32_t t = bell.ticket();
  std::thread waiter([&] {
    bell.wait(t, 60000);
    woke = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  bell.ring();
  waiter.join();  // a lost wake-up would hang here for a minute and time the test out
  EXPECT_TRUE(woke.load());
}

TEST(LatencyHistogram, BucketsAreContiguousAndNarrow) {
  for (int i = 0; i + 1 < LatencyHistogram::kBuckets; ++i) {
    ASSERT_EQ(LatencyHistogram::bucket_hi_us(i), LatencyHistogram::bucket_lo_us(i + 1)) << i;
    ASSERT_EQ(LatencyHistogram::bucket_of(LatencyHistogram::bucket_lo_us(i)), i);
    const double lo = static_cast<double>(LatencyHistogram::bucket_lo_us(i));
    const double hi = static_cast<double>(LatencyHistogram::bucket_hi_us(i));
    if (lo >= 8) {
      ASSERT_LE((hi - lo) / lo, 0.125 + 1e-12) << i;
    }
  }
  EXPECT_EQ(LatencyHistogram::bucket_of(-5), 0);
  EXPECT_EQ(LatencyHistogram::bucket_of(int64_t{1} << 40), LatencyHistogram::kBuckets - 1);
}

TEST(LatencyHistogram, PercentilesWithinBucketResolution) {
  LatencyHistogram h;
  // 1..1000 ms uniformly: p50 = 500 ms, p99 = 990 ms.
  for (int ms = 1; ms <= 1000; ++ms) h.record_us(ms * 1000);
  const auto s = h.snapshot();
  EXPECT_EQ(s.total, 1000u);
  EXPECT_NEAR(s.percentile_ms(0.5), 500.0, 500.0 * 0.0625);
  EXPECT_NEAR(s.percentile_ms(0.99), 990.0, 990.0 * 0.0625);
  EXPECT_NEAR(s.mean_ms(), 500.5, 1e-9);
  EXPECT_EQ(s.max_us, 1000000);
  EXPECT_EQ(LatencyHistogram::Snapshot().percentile_ms(0.5), 0.0);
}

TEST(LatencyHistogram, SinceGivesTheLastIntervalOnly) {
  LatencyHistogram h;
  for (int i = 0; i < 100; ++i) h.record_us(100);
  const auto a = h.snapshot();
  for (int i = 0; i < 10; ++i) h.record_us(50000);
  const auto d = h.snapshot().since(a);
  EXPECT_EQ(d.total, 10u);
  EXPECT_NEAR(d.percentile_ms(0.5), 50.0, 50.0 * 0.0625);
}

TEST(LatencyHistogramStress, ConcurrentReaderNeverSeesMoreThanWritten) {
  LatencyHistogram h;
  constexpr int kCount = 100000;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (int i = 0; i < kCount; ++i) h.record_us(i % 5000);
    done = true;
  });
  uint64_t last = 0;
  bool monotonic = true;
  while (!done.load()) {
    const auto s = h.snapshot();
    monotonic = monotonic && s.total >= last && s.total <= kCount;
    last = s.total;
  }
  writer.join();
  EXPECT_TRUE(monotonic);
  EXPECT_EQ(h.snapshot().total, static_cast<uint64_t>(kCount));
}

}  // namespace
}  // namespace rdslam
