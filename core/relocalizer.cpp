#include "core/relocalizer.h"

#include <cmath>
#include <vector>

namespace rdslam {

int global_match(const Features& f, const MapSnapshot& snap, const FeatureParams& params,
                 int* pairs, int cap) {
  const int rows = snap.rows();
  if (rows < 2 || f.count == 0) return 0;
  int n = 0;
  if (f.binary) {
    const int max_d = params.orb_max_distance;
    for (int j = 0; j < f.count && n < cap; ++j) {
      int b1 = 1 << 20, b2 = 1 << 20, br = -1;
      const uint8_t* q = f.desc_ptr(j);
      for (int r = 0; r < rows; ++r) {
        const int d = hamming256(q, snap.desc.ptr<uint8_t>(r));
        if (d < b1) {
          b2 = b1;
          b1 = d;
          br = r;
        } else if (d < b2) {
          b2 = d;
        }
      }
      if (br >= 0 && b1 <= max_d && b1 < 0.75 * b2) {
        pairs[2 * n] = j;
        pairs[2 * n + 1] = br;
        ++n;
      }
    }
  } else {
    if (!snap.kdtree) return 0;
    cv::Mat idx, dist;
    snap.kdtree->knnSearch(f.desc.rowRange(0, f.count), idx, dist, 2, cv::flann::SearchParams(32));
    for (int j = 0; j < f.count && n < cap; ++j) {
      const float d1 = std::sqrt(dist.at<float>(j, 0)), d2 = std::sqrt(dist.at<float>(j, 1));
      const int r = idx.at<int>(j, 0);
      // Paper Sec. 3: matched when c = ||p(x) - p(N1)|| / ||p(x) - p(N2)|| < 0.6.
      if (r < 0 || r >= rows || d2 <= 0 || d1 / d2 >= params.sift_ratio) continue;
      pairs[2 * n] = j;
      pairs[2 * n + 1] = r;
      ++n;
    }
  }
  // One feature per map point: keep the first claim (rare duplicates are harmless for RANSAC
  // but would double-count inliers).
  std::vector<char> used(static_cast<size_t>(rows), 0);
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
