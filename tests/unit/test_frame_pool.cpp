// Frame pool (core/frame_pool.h): preallocated slots, free list, cross-thread release.
#include <gtest/gtest.h>

#include <atomic>
#include <set>
#include <stdexcept>
#include <thread>

#include "core/frame_pool.h"

namespace rdslam {
namespace {

TEST(FramePool, PreallocatesEverySlotAtTheRequestedSizeAndFormat) {
  FramePool gray(4, 64, 48, PixelFormat::kGray8);
  ASSERT_EQ(gray.slots(), 4);
  for (uint32_t i = 0; i < 4; ++i) {
    EXPECT_EQ(gray.frame(i).image.cols, 64);
    EXPECT_EQ(gray.frame(i).image.rows, 48);
    EXPECT_EQ(gray.frame(i).image.type(), CV_8UC1);
  }
  FramePool bgr(3, 32, 16, PixelFormat::kBgr8);
  EXPECT_EQ(bgr.frame(2).image.type(), CV_8UC3);
  EXPECT_EQ(bgr.frame(2).format, PixelFormat::kBgr8);
  // Distinct buffers: a slot written by capture never aliases another slot.
  EXPECT_NE(bgr.frame(0).image.data, bgr.frame(1).image.data);
}

TEST(FramePool, RejectsUnusableSizes) {
  EXPECT_THROW(FramePool(0, 64, 48, PixelFormat::kGray8), std::invalid_argument);
  EXPECT_THROW(FramePool(2, 0, 48, PixelFormat::kGray8), std::invalid_argument);
}

TEST(FramePool, EverySlotIsHandedOutOnceUntilReleased) {
  FramePool pool(5, 8, 8, PixelFormat::kGray8);
  std::set<uint32_t> got;
  uint32_t s = 0;
  while (pool.try_acquire(s)) got.insert(s);
  EXPECT_EQ(got.size(), 5u);
  EXPECT_EQ(*got.rbegin(), 4u);
  EXPECT_FALSE(pool.try_acquire(s));
  EXPECT_TRUE(pool.release(3));
  ASSERT_TRUE(pool.try_acquire(s));
  EXPECT_EQ(s, 3u);
  EXPECT_FALSE(pool.release(5)) << "not a slot of this pool";
  EXPECT_FALSE(pool.release(0xFFFFFFFFu));
}

TEST(FramePool, WaitAcquireTimesOutWhenEmptyAndWakesOnRelease) {
  FramePool pool(3, 8, 8, PixelFormat::kGray8);
  uint32_t s = 0;
  while (pool.try_acquire(s)) {
  }
  EXPECT_FALSE(pool.wait_acquire(s, 10));
  std::atomic<bool> released{false};
  std::thread releaser([&] {
    released = true;
    pool.release(1);
  });
  bool got = false;
  // Wait in bounded steps until the release arrives (no wall-clock assertion).
  for (int i = 0; i < 600 && !got; ++i) got = pool.wait_acquire(s, 100);
  releaser.join();
  EXPECT_TRUE(released.load());
  ASSERT_TRUE(got);
  EXPECT_EQ(s, 1u);
}

TEST(FramePoolStress, AcquireAndReleaseOnTwoThreadsConserveSlots) {
  constexpr int kSlots = 4;
  constexpr int kRounds = 50000;
  FramePool pool(kSlots, 8, 8, PixelFormat::kGray8);
  SpscRing<uint32_t> handoff(kSlots);  // acquirer -> releaser
  std::thread releaser([&] {
    int n = 0;
    uint32_t s = 0;
    while (n < kRounds) {
      if (handoff.try_pop(s)) {
        pool.frame(s).seq += 1;  // the releaser owns the slot now
        pool.release(s);
        ++n;
      }
    }
  });
  uint32_t s = 0;
  for (int i = 0; i < kRounds; ++i) {
    while (!pool.wait_acquire(s, 100)) {
    }
    ASSERT_LT(s, static_cast<uint32_t>(kSlots));
    while (!handoff.try_push(s)) {
    }
  }
  releaser.join();
  uint64_t total = 0;
  for (uint32_t i = 0; i < kSlots; ++i) total += pool.frame(i).seq;
  EXPECT_EQ(total, static_cast<uint64_t>(kRounds));
  EXPECT_EQ(pool.free_slots(), static_cast<uint32_t>(kSlots));
}

}  // namespace
}  // namespace rdslam
