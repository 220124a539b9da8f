// The keyframe database (core/keyframe_database.h): a query finds the keyframe a frame was
// taken near among many, removal and epoch filters work, the L1 score is DBoW2's, and a query
// does not allocate once its scratch is reserved.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/keyframe_database.h"
#include "core/slam.h"
#include "drivers/synth_source.h"
#include "tests/unit/alloc_counting.h"

namespace rdslam {
namespace {

constexpr int kWords = 5000;

// A synthetic "place": 300 words drawn at random, weights uniform (already L1-normalised).
BowVector place(uint64_t seed, int n = 300) {
  std::mt19937_64 rng(seed);
  std::vector<int> w;
  while (static_cast<int>(w.size()) < n) {
    const int x = static_cast<int>(rng() % kWords);
    if (std::find(w.begin(), w.end(), x) == w.end()) w.push_back(x);
  }
  std::sort(w.begin(), w.end());
  BowVector b;
  b.reserve(n);
  b.size = n;
  for (int i = 0; i < n; ++i) {
    b.words[i] = w[i];
    b.weights[i] = 1.f / n;
  }
  return b;
}

// `keep` of the words of `b` plus other random words: a view of the same place.
BowVector view_of(const BowVector& b, int keep, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<int> w(b.words.begin(), b.words.begin() + b.size);
  std::shuffle(w.begin(), w.end(), rng);
  w.resize(keep);
  while (static_cast<int>(w.size()) < b.size) {  // new words: none of the place's
    const int x = static_cast<int>(rng() % kWords);
    if (std::find(b.words.begin(), b.words.begin() + b.size, x) != b.words.begin() + b.size) {
      continue;
    }
    if (std::find(w.begin(), w.end(), x) == w.end()) w.push_back(x);
  }
  std::sort(w.begin(), w.end());
  BowVector v;
  v.reserve(b.size);
  v.size = b.size;
  for (int i = 0; i < b.size; ++i) {
    v.words[i] = w[i];
    v.weights[i] = 1.f / b.size;
  }
  return v;
}

TEST(KeyframeDatabase, FindsTheKeyframeOfThePlaceAmongMany) {
  KeyframeDatabaseBuilder builder(kWords);
  std::vector<BowVector> places;
  for (int k = 0; k < 150; ++k) {
    places.push_back(place(1000 + k));
    builder.add(0, 10 * k, places.back());
  }
  const auto db = builder.build();
  ASSERT_EQ(db->size(), 150);
  PlaceQueryScratch s;
  s.reserve(150);
  PlaceQueryParams p;
  p.max_candidates = 3;
  PlaceCandidate c[3];
  for (int k = 0; k < 150; k += 7) {
    const BowVector q = view_of(places[k], 120, 77 + k);  // 40% of its words seen again
    const int n = db->query(q, p, s, c, 3);
    ASSERT_GE(n, 1) << k;
    EXPECT_EQ(c[0].keyframe, 10 * k);
    EXPECT_EQ(c[0].epoch, 0u);
    // DBoW2's L1 score of two uniform vectors sharing 120 of 300 words: 120/300.
    EXPECT_NEAR(c[0].score, 0.4f, 1e-4);
    EXPECT_EQ(c[0].common_words, 120);
    for (int i = 1; i < n; ++i) EXPECT_LE(c[i].score, c[i - 1].score);
  }
  // Identical vector: score 1.
  ASSERT_EQ(db->query(places[5], p, s, c, 3), 1);  // the others share < 0.8 x 300 words
  EXPECT_NEAR(c[0].score, 1.f, 1e-4);
}

TEST(KeyframeDatabase, RemovedKeyframesAreNotFoundAndBuildIsSharedUntilAChange) {
  KeyframeDatabaseBuilder builder(kWords);
  const BowVector a = place(1), b = place(2);
  builder.add(0, 1, a);
  builder.add(0, 2, b);
  const auto db1 = builder.build();
  EXPECT_EQ(builder.build(), db1) << "unchanged: the same immutable database";
  builder.remove(0, 1);
  const auto db2 = builder.build();
  EXPECT_NE(db2, db1);
  EXPECT_EQ(db2->size(), 1);
  PlaceQueryScratch s;
  PlaceQueryParams p;
  PlaceCandidate c[3];
  // Only keyframe 2 is left; it shares a few words with `a` by chance.
  ASSERT_EQ(db2->query(a, p, s, c, 3), 1);
  EXPECT_EQ(c[0].keyframe, 2) << "keyframe 1 was removed";
  EXPECT_LT(c[0].score, 0.2f);
  ASSERT_EQ(db1->query(a, p, s, c, 3), 1) << "an older database is unaffected";
  EXPECT_EQ(c[0].keyframe, 1);
  // retain(): keep only even ids.
  builder.add(0, 3, place(3));
  builder.add(0, 4, place(4));
  builder.retain(0, [](int kf) { return kf % 2 == 0; });
  EXPECT_FALSE(builder.contains(0, 3));
  EXPECT_TRUE(builder.contains(0, 4));
  EXPECT_TRUE(builder.contains(0, 2));
  builder.clear();
  EXPECT_EQ(builder.build()->size(), 0);
}

TEST(KeyframeDatabase, QueriesCanBeLimitedToOneMapEpoch) {
  KeyframeDatabaseBuilder builder(kWords);
  const BowVector a = place(5);
  builder.add(0, 7, a);  // the same place in two maps
  builder.add(1, 3, view_of(a, 250, 9));
  const auto db = builder.build();
  PlaceQueryScratch s;
  PlaceQueryParams p;
  PlaceCandidate c[3];
  ASSERT_EQ(db->query(a, p, s, c, 3), 2);  // all epochs
  EXPECT_EQ(c[0].epoch, 0u);
  EXPECT_EQ(c[0].keyframe, 7);
  EXPECT_EQ(c[1].epoch, 1u);
  EXPECT_EQ(c[1].keyframe, 3);
  p.epoch = 1;
  ASSERT_EQ(db->query(a, p, s, c, 3), 1);
  EXPECT_EQ(c[0].epoch, 1u);
  EXPECT_EQ(c[0].keyframe, 3);
}

TEST(KeyframeDatabase, QueryDoesNotAllocate) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  KeyframeDatabaseBuilder builder(kWords);
  for (int k = 0; k < 150; ++k) builder.add(0, k, place(500 + k));
  const auto db = builder.build();
  PlaceQueryScratch s;
  s.reserve(150);  // what the relocalizer does for mapper.max_keyframes
  PlaceQueryParams p;
  PlaceCandidate c[3];
  const BowVector q = view_of(place(520), 150, 1);
  const uint64_t m0 = g_malloc_calls.load(), n0 = g_new_calls.load();
  int found = 0;
  for (int i = 0; i < 20; ++i) found += db->query(q, p, s, c, 3) > 0 && c[0].keyframe == 20;
  EXPECT_EQ(g_malloc_calls.load() - m0, 0u);
  EXPECT_EQ(g_new_calls.load() - n0, 0u);
  EXPECT_EQ(found, 20);
#endif
}

TEST(KeyframeDatabase, MapperKeepsItEqualToTheMapsKeyframes) {
  // The mapper adds accepted keyframes and drops removed ones: with a cap of 6 keyframes the
  // oldest go while static_xyz is mapped, and every published snapshot's database holds exactly
  // its keyframes (this epoch), no culled one.
  SourceOptions so;
  std::unique_ptr<FrameSource> src = open_synth_source("static_xyz", so, 150);
  const CameraModel cam = *src->camera();
  SlamParams params;
  params.mapper.max_keyframes = 6;
  auto link = make_slam_link(params, 8);
  ASSERT_TRUE(link->vocabulary) << "ORB mode loads the vocabulary";
  Tracker tracker(params.tracker, params.features, params.mapper.ba, params.parsac, cam, link,
                  params.mapper.max_points, params.mapper.max_keyframes);
  Mapper mapper(params.mapper, params.features, cam, link);
  Frame frame;
  int checked = 0;
  uint64_t seen = 0;
  while (src->read(frame, 1000) == SourceStatus::kOk) {
    tracker.track(frame);
    while (mapper.step(0)) {
    }
    const auto snap = link->index.acquire();
    if (!snap || link->index.version() == seen) continue;
    seen = link->index.version();
    ASSERT_TRUE(snap->places);
    std::vector<int> in_db;
    for (int e = 0; e < snap->places->size(); ++e) {
      EXPECT_EQ(snap->places->epoch(e), snap->epoch);
      in_db.push_back(snap->places->keyframe(e));
    }
    std::vector<int> kfs = snap->kf_ids;
    std::sort(in_db.begin(), in_db.end());
    std::sort(kfs.begin(), kfs.end());
    EXPECT_EQ(in_db, kfs);
    ++checked;
  }
  EXPECT_GT(mapper.stats().keyframes_culled, 0) << "the cap removed keyframes";
  EXPECT_GT(checked, 5);
}

}  // namespace
}  // namespace rdslam
