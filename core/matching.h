// Descriptor matching, one module for every matcher of rdslam: the initializer (two frames),
// the tracker (motion-model and map-point projection search), the mapper (triangulation along
// epipolar lines, fusion of map points into keyframes) and the relocalizer (global search).
//
// A match is the nearest candidate descriptor, accepted by the rule of its purpose: distance at
// most `max_distance` and at most `ratio` times the second-nearest (the 2-NN ratio test; the
// paper's matching confidence c = d1/d2 < 0.6 in SIFT mode, Sec. 3; ratio 1 disables the test,
// d1 <= d2 always). Each purpose has its own rule with one default per feature mode
// (MatchingParams, config section `matching`); distances are Hamming bits of 256 (ORB) or L2
// of unit-512-norm floats (SIFT). The feature mode is decided in one place,
// FeatureParams::binary().
//
// Also here: the pyramid level at which a map point is predicted to be seen (tracker and
// mapper), and the one-to-one assignment by best distance (initializer, triangulation).
//
// Features (core/features.h) carries MatchingParams in FeatureParams::matching, so this
// header does not include features.h; best_of() takes any feature set with desc_ptr(j).
//
// Ownership: plain values and functions over caller buffers; ClaimTable owns its buffers
// (they grow to the largest size once). Threads: any; one ClaimTable per thread.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "core/params.h"

namespace rdslam {

// Descriptor distance: Hamming bits (binary) or L2 (float), as a double.
double descriptor_distance(const uint8_t* a, const uint8_t* b, bool binary);

inline int hamming256(const uint8_t* a, const uint8_t* b) {
  const uint64_t* x = reinterpret_cast<const uint64_t*>(a);
  const uint64_t* y = reinterpret_cast<const uint64_t*>(b);
  return __builtin_popcountll(x[0] ^ y[0]) + __builtin_popcountll(x[1] ^ y[1]) +
         __builtin_popcountll(x[2] ^ y[2]) + __builtin_popcountll(x[3] ^ y[3]);
}

// What a match is for. Each purpose has its own acceptance rule.
enum class MatchPurpose : uint8_t {
  kMotion = 0,   // tracker: previous frame's points, motion-model prediction
  kLocalMap,     // tracker: projection of the matching index's points
  kInit,         // initializer: reference frame to current frame
  kTriangulate,  // mapper: new keyframe to a related keyframe, along the epipolar line
  kFuse,         // mapper: an existing map point into a keyframe (nearest only)
  kRelocalize,   // relocalizer: every feature against every indexed point
};
constexpr int kMatchPurposes = 6;
const char* to_string(MatchPurpose p);

// The nearest and second-nearest candidate seen so far. `index` is -1 until a candidate is
// offered; on equal distances the first offered stays nearest.
struct BestTwo {
  double d1 = 1e30;
  double d2 = 1e30;
  int index = -1;
  void offer(double d, int i) {
    if (d < d1) {
      d2 = d1;
      d1 = d;
      index = i;
    } else if (d < d2) {
      d2 = d;
    }
  }
};

struct MatchRule {
  double max_distance = 64.0;
  double ratio = 1.0;  // 2-NN ratio; 1 = no ratio test
  bool accepts(const BestTwo& b) const {
    return b.index >= 0 && b.d1 <= max_distance && b.d1 <= ratio * b.d2;
  }
};

struct MatchingParams {
  // Defaults: ORB limits as tuned per purpose (Hamming of 256 bits; the motion and projection
  // searches are gated by geometry and accept more, the two-view matchers less); SIFT the
  // paper's c < 0.6 with an L2 limit of 250 everywhere (fusion takes the nearest only).
  MatchRule orb[kMatchPurposes] = {{64, 0.9}, {64, 0.9}, {50, 0.9},
                                   {50, 0.8}, {50, 1.0}, {64, 0.75}};
  MatchRule sift[kMatchPurposes] = {{250, 0.6}, {250, 0.6}, {250, 0.6},
                                    {250, 0.6}, {250, 1.0}, {250, 0.6}};

  const MatchRule& rule(MatchPurpose p, bool binary) const {
    return (binary ? orb : sift)[static_cast<int>(p)];
  }
  // Keys `<mode>_<purpose>_max_distance` and `<mode>_<purpose>_ratio`, e.g.
  // matching.orb_local_ratio (ranges: ORB distance 1..256, SIFT 1..1000, ratio 0.1..1).
  void visit(ParamVisitor& v);
};

// The best two of the candidate features cand[0..n) of `f` for descriptor `d`; a candidate j
// with skip(j) true is not offered.
template <class FeatureSet, class Skip>
BestTwo best_of(const uint8_t* d, const FeatureSet& f, const int* cand, int n, bool binary,
                Skip&& skip) {
  BestTwo best;
  for (int k = 0; k < n; ++k) {
    const int j = cand[k];
    if (skip(j)) continue;
    best.offer(descriptor_distance(d, f.desc_ptr(j), binary), j);
  }
  return best;
}
template <class FeatureSet>
BestTwo best_of(const uint8_t* d, const FeatureSet& f, const int* cand, int n, bool binary) {
  return best_of(d, f, cand, n, binary, [](int) { return false; });
}
// The best two of the first `rows` rows of `desc` (one descriptor per row) for `d`.
BestTwo best_of_rows(const uint8_t* d, const cv::Mat& desc, int rows, bool binary);

// Pyramid level at which a point is predicted to be seen from distance `dist` (ORB-SLAM's scale
// prediction): `max_dist` is the largest distance of the point's scale invariance, 1.2 the
// scale factor it was computed with; clamped to [0, levels - 1].
int predict_level(double max_dist, double dist, double log_scale_factor, int levels);

// One-to-one assignment of queries to targets by best distance: a target claimed by a closer
// query is taken from the one that held it (that query is left without a match).
class ClaimTable {
 public:
  void reset(int queries, int targets);
  void offer(int query, int target, double d) {
    if (d >= dist_[target]) return;
    if (query_of_[target] >= 0) target_of_[query_of_[target]] = -1;
    dist_[target] = d;
    query_of_[target] = query;
    target_of_[query] = target;
  }
  int target_of(int query) const { return target_of_[query]; }
  int matched() const;

 private:
  std::vector<int> target_of_, query_of_;
  std::vector<double> dist_;
};

}  // namespace rdslam
