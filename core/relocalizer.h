// Global matching for relocalization after loss (Sec. 3): every feature of the frame is
// matched against all reference features of the active matching index. SIFT mode queries the
// index's FLANN KD-tree for the two nearest neighbours and applies the paper's matching
// confidence c = d1/d2 < 0.6; ORB mode compares against every point (Hamming distance,
// popcount) with its 2-NN ratio (matching.orb_reloc_*, core/matching.h). The tracker then estimates
// the pose robustly from the pairs (core/pose_estimation.h) and extends the matches by projection.
//
// Ownership: pure function over caller buffers. Threads: tracker thread. Allocates: one byte
// per snapshot row to keep one feature per map point (both modes), and FLANN's result
// matrices in SIFT mode.
#pragma once

#include "core/features.h"
#include "core/match_index.h"

namespace rdslam {

// Writes (feature index, snapshot row) pairs into `pairs` (2 ints each, at most `cap` pairs)
// and returns their number. Each snapshot row is used at most once (best distance wins).
int global_match(const Features& f, const MapSnapshot& snap, const FeatureParams& params,
                 int* pairs, int cap);

}  // namespace rdslam
