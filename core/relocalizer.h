// Matching for relocalization after loss (Sec. 3): (feature, snapshot row) pairs from which the
// tracker estimates the pose robustly (core/pose_estimation.h) and extends the matches by
// projection (Tracker::relocalize).
//
// ORB mode with a vocabulary (core/vocabulary.h; the default, SlamLink::vocabulary): place
// recognition first. The frame's bag-of-words vector queries the snapshot's keyframe database
// (MapSnapshot::places, core/keyframe_database.h) for the best `reloc_candidates` keyframes of
// the current map; the frame's features are then matched only against those keyframes' points
// (MapSnapshot::kf_rows), and only within one node of the vocabulary tree at level
// `reloc_node_level` (DBoW2's direct index, as ORB-SLAM2's SearchByBoW), with the 2-NN ratio
// of matching.orb_reloc_* (core/matching.h). Work per LOST frame is bounded by the keyframe
// cap (the query) and by candidates x features per keyframe (the matching), not by the map.
//
// Without a vocabulary (stages built by hand in tests) ORB mode compares every feature with
// every indexed point (brute-force Hamming, cost proportional to the map). SIFT mode queries the
// index's FLANN KD-tree (the paper's global matching, bounded by FLANN's 32 checks per feature)
// with the paper's c = d1/d2 < 0.6.
//
// Ownership: the tracker owns one Relocalizer and its scratch (sized at construction from the
// caps: feature count, mapper.max_keyframes, mapper.max_points). Threads: tracker thread.
// Allocation: none in ORB mode with a vocabulary once constructed (unless a map exceeds its
// caps, then its buffers grow once); the brute-force path's scratch grows to the largest map;
// SIFT mode allocates FLANN's result matrices.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "core/features.h"
#include "core/keyframe_database.h"
#include "core/match_index.h"
#include "core/vocabulary.h"

namespace rdslam {

struct RelocalizerParams {
  int candidates = 3;  // keyframes from place recognition whose points are matched
  int node_level = 2;  // vocabulary level of the direct index (features matched within a node)
};

class Relocalizer {
 public:
  Relocalizer(const RelocalizerParams& params, const FeatureParams& features,
              std::shared_ptr<const Vocabulary> vocabulary, int max_keyframes, int max_points);
  // Writes (feature index, snapshot row) pairs into `pairs` (2 ints each, at most `cap` pairs)
  // and returns their number. Each snapshot row is used at most once.
  int match(const Features& f, const MapSnapshot& snap, uint32_t epoch, int* pairs, int cap);
  // Recovery (several map epochs in `places`): the epoch of the keyframe that place recognition
  // ranks first for the frame, over all epochs; -1 without a candidate or without places.
  int64_t best_epoch(const Features& f, const KeyframeDatabase& places);
  // The place-recognition candidates of the last match() (ORB with a vocabulary).
  int candidate_count() const { return n_cands_; }
  const PlaceCandidate* candidates() const { return cands_.data(); }
  bool uses_places() const { return vocabulary_ != nullptr && binary_; }

 private:
  int match_places(const Features& f, const MapSnapshot& snap, uint32_t epoch, int* pairs, int cap);
  int match_all(const Features& f, const MapSnapshot& snap, int* pairs, int cap);
  int claim_rows(int n, int* pairs);

  RelocalizerParams params_;
  FeatureParams fparams_;
  bool binary_ = true;
  std::shared_ptr<const Vocabulary> vocabulary_;
  // Place recognition scratch.
  BowVector bow_;
  Vocabulary::Scratch voc_scratch_;
  std::vector<int> feat_node_;
  PlaceQueryScratch query_scratch_;
  std::vector<PlaceCandidate> cands_;
  int n_cands_ = 0;
  std::vector<int> rows_, row_node_, bucket_start_, bucket_rows_;
  std::vector<uint8_t> used_;  // per snapshot row: gathered / claimed
  cv::Mat idx_, dist_;         // SIFT: FLANN's 2-NN indices and squared distances
};

}  // namespace rdslam
