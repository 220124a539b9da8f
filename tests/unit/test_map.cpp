// Map bookkeeping: observations on both sides and Sec. 4's 90% keyframe rule (Map::redundancy),
// the one rule the mapper's culling and the map updater's keyframe check share.
#include <gtest/gtest.h>

#include "core/map.h"

namespace rdslam {
namespace {

// One keyframe with `n` features, each with a point; the first `invalid` points are invalid
// and the next `shared` are observed by 3 more keyframes.
Map keyframe_with_points(int n, int invalid, int shared) {
  Map m;
  for (int k = 0; k < 4; ++k) {
    Keyframe& kf = m.keyframes[k];
    kf.id = k;
    kf.point_of.assign(n, -1);
  }
  for (int i = 0; i < n; ++i) {
    MapPoint& p = m.points[i];
    p.id = i;
    p.valid = i >= invalid;
    EXPECT_TRUE(m.add_observation(i, 0, i));
    if (i >= invalid && i < invalid + shared) {
      for (int k = 1; k < 4; ++k) EXPECT_TRUE(m.add_observation(i, k, i));
    }
  }
  return m;
}

TEST(MapRedundancy, CountsInvalidAndSharedPoints) {
  const Map m = keyframe_with_points(100, 40, 50);
  const Map::Redundancy r = m.redundancy(m.keyframes.at(0));
  EXPECT_EQ(r.total, 100);
  EXPECT_EQ(r.redundant, 90);
  // "larger than 90% of its total point number": 90 of 100 is not, 91 is.
  EXPECT_FALSE(r.exceeds(0.9));
  const Map m91 = keyframe_with_points(100, 41, 50);
  EXPECT_TRUE(m91.redundancy(m91.keyframes.at(0)).exceeds(0.9));
}

TEST(MapRedundancy, PointsSeenByTwoOtherKeyframesAreNotShared) {
  Map m = keyframe_with_points(10, 0, 0);
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(m.add_observation(i, 1, i));
    ASSERT_TRUE(m.add_observation(i, 2, i));  // 3 observations in all
  }
  const Map::Redundancy r = m.redundancy(m.keyframes.at(0));
  EXPECT_EQ(r.total, 10);
  EXPECT_EQ(r.redundant, 0);
}

TEST(MapRedundancy, FeaturesWithoutPointsAndErasedPointsDoNotCount) {
  Map m = keyframe_with_points(10, 10, 0);
  m.keyframes.at(0).point_of.resize(20, -1);  // 10 features without a point
  m.erase_point(0);
  const Map::Redundancy r = m.redundancy(m.keyframes.at(0));
  EXPECT_EQ(r.total, 9);
  EXPECT_EQ(r.redundant, 9);
  EXPECT_TRUE(r.exceeds(0.9));
  EXPECT_FALSE(Map{}.redundancy(Keyframe{}).exceeds(0.0));  // no points: never redundant
}

}  // namespace
}  // namespace rdslam
