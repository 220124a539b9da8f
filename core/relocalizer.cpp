#include "core/relocalizer.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/matching.h"

namespace rdslam {

int global_match(const Features& f, const MapSnapshot& snap, const FeatureParams& params,
                 GlobalMatchScratch& scratch, int* pairs, int cap) {
  const int rows = snap.rows();
  if (rows < 2 || f.count == 0) return 0;
  int n = 0;
  const bool bin = params.binary();
  const MatchRule& rule = params.matching.rule(MatchPurpose::kRelocalize, bin);
  if (bin) {
    for (int j = 0; j < f.count && n < cap; ++j) {
      const BestTwo best = best_of_rows(f.desc_ptr(j), snap.desc, rows, true);
      if (!rule.accepts(best)) continue;
      pairs[2 * n] = j;
      pairs[2 * n + 1] = best.index;
      ++n;
    }
  } else {
    if (!snap.kdtree) return 0;
    cv::Mat& idx = scratch.idx;
    cv::Mat& dist = scratch.dist;
    snap.kdtree->knnSearch(f.desc.rowRange(0, f.count), idx, dist, 2, cv::flann::SearchParams(32));
    for (int j = 0; j < f.count && n < cap; ++j) {
      // Paper Sec. 3: matched when c = ||p(x) - p(N1)|| / ||p(x) - p(N2)|| < 0.6.
      BestTwo best;
      best.d1 = std::sqrt(dist.at<float>(j, 0));
      best.d2 = std::sqrt(dist.at<float>(j, 1));
      const int r = idx.at<int>(j, 0);
      best.index = r;
      if (r < 0 || r >= rows || best.d2 <= 0 || !rule.accepts(best)) continue;
      pairs[2 * n] = j;
      pairs[2 * n + 1] = r;
      ++n;
    }
  }
  // One feature per map point: keep the first claim (rare duplicates are harmless for RANSAC
  // but would double-count inliers).
  std::vector<uint8_t>& used = scratch.used;
  if (used.size() < static_cast<size_t>(rows)) used.resize(static_cast<size_t>(rows));
  std::fill(used.begin(), used.begin() + rows, uint8_t{0});
  int k = 0;
  for (int i = 0; i < n; ++i) {
    const int r = pairs[2 * i + 1];
    if (used[r]) continue;
    used[r] = 1;
    pairs[2 * k] = pairs[2 * i];
    pairs[2 * k + 1] = r;
    ++k;
  }
  return k;
}

}  // namespace rdslam
