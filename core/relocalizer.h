// Global matching for relocalization after loss (Sec. 3): every feature of the frame is
// matched against all reference features of the active matching index. SIFT mode queries the
// index's FLANN KD-tree for the two nearest neighbours and applies the paper's matching
// confidence c = d1/d2 < 0.6; ORB mode compares against every point (Hamming distance,
// popcount) with its 2-NN ratio (matching.orb_reloc_*, core/matching.h). The tracker then estimates
// the pose robustly from the pairs (core/pose_estimation.h) and extends the matches by projection.
//
// Ownership: a function over caller buffers; the caller owns the GlobalMatchScratch (the
// tracker keeps one). Threads: tracker thread. Allocates only when the scratch grows: to the
// largest snapshot row count (one byte per row, bounded by mapper.max_points) and, in SIFT
// mode, FLANN's result matrices to the largest feature count.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "core/features.h"
#include "core/match_index.h"

namespace rdslam {

struct GlobalMatchScratch {
  std::vector<uint8_t> used;  // per snapshot row: claimed by a feature
  cv::Mat idx, dist;          // SIFT: FLANN's 2-NN indices and squared distances
};

// Writes (feature index, snapshot row) pairs into `pairs` (2 ints each, at most `cap` pairs)
// and returns their number. Each snapshot row is used at most once: the first feature (in
// feature order) that passes the rule keeps it.
int global_match(const Features& f, const MapSnapshot& snap, const FeatureParams& params,
                 GlobalMatchScratch& scratch, int* pairs, int cap);

}  // namespace rdslam
