// core/match_index: the double-buffered matching index. Publishing swaps the active snapshot
// atomically; a snapshot the tracker still holds stays valid and unchanged; retired
// snapshots are freed by the mapper once the tracker let go.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/match_index.h"

namespace rdslam {
namespace {

std::shared_ptr<MapSnapshot> snap(uint64_t version, int rows) {
  auto s = std::make_shared<MapSnapshot>();
  s->version = version;
  for (int i = 0; i < rows; ++i) {
    s->ids.push_back(i);
    s->p_world.emplace_back(i, 0, 1);
    s->row_of.emplace(i, i);
  }
  return s;
}

TEST(MatchIndex, PublishSwapsActiveSnapshot) {
  MatchIndex idx;
  EXPECT_EQ(idx.acquire(), nullptr);
  idx.publish(snap(1, 3));
  EXPECT_EQ(idx.version(), 1u);
  EXPECT_EQ(idx.acquire()->rows(), 3);
  idx.publish(snap(2, 5));
  EXPECT_EQ(idx.acquire()->version, 2u);
  EXPECT_EQ(idx.acquire()->find(4), 4);
  EXPECT_EQ(idx.acquire()->find(9), -1);
}

TEST(MatchIndex, HeldSnapshotSurvivesSwapAndIsFreedByCollect) {
  MatchIndex idx;
  idx.publish(snap(1, 2));
  std::weak_ptr<const MapSnapshot> weak;
  {
    std::shared_ptr<const MapSnapshot> held = idx.acquire();  // the tracker's copy
    weak = held;
    idx.publish(snap(2, 4));
    idx.collect();
    ASSERT_FALSE(weak.expired());
    EXPECT_EQ(held->rows(), 2);  // unchanged while in use
  }
  EXPECT_FALSE(weak.expired());  // the tracker let go, but the mapper frees it...
  idx.collect();
  EXPECT_TRUE(weak.expired());  // ...here, in the mapper thread
}

TEST(MatchIndex, ConcurrentPublishAndAcquire) {
  MatchIndex idx;
  idx.publish(snap(1, 1));
  std::atomic<bool> done{false};
  std::thread tracker([&] {
    uint64_t last = 0;
    while (!done.load()) {
      auto s = idx.acquire();
      ASSERT_NE(s, nullptr);
      ASSERT_GE(s->version, last);  // versions never go back
      ASSERT_EQ(s->rows(), s->version == 1 ? 1 : static_cast<int>(s->version % 7) + 1);
      last = s->version;
    }
  });
  for (uint64_t v = 2; v < 2000; ++v) idx.publish(snap(v, static_cast<int>(v % 7) + 1));
  done = true;
  tracker.join();
  idx.collect();
}

}  // namespace
}  // namespace rdslam
