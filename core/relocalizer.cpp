#include "core/relocalizer.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/matching.h"

namespace rdslam {

Relocalizer::Relocalizer(const RelocalizerParams& params, const FeatureParams& features,
                         std::shared_ptr<const Vocabulary> vocabulary, int max_keyframes,
                         int max_points)
    : params_(params),
      fparams_(features),
      binary_(features.binary()),
      vocabulary_(std::move(vocabulary)) {
  const int feats = features.max_features + 64;
  used_.assign(static_cast<size_t>(max_points) + 4096, 0);
  if (!uses_places()) return;
  bow_.reserve(feats);
  voc_scratch_.reserve(feats);
  feat_node_.assign(static_cast<size_t>(feats), 0);
  query_scratch_.reserve(max_keyframes + 64);
  cands_.resize(static_cast<size_t>(std::max(1, params.candidates)));
  rows_.resize(static_cast<size_t>(params.candidates) * static_cast<size_t>(feats));
  row_node_.resize(rows_.size());
  bucket_rows_.resize(rows_.size());
  bucket_start_.assign(static_cast<size_t>(vocabulary_->nodes()) + 1, 0);
}

int Relocalizer::match(const Features& f, const MapSnapshot& snap, uint32_t epoch, int* pairs,
                       int cap) {
  n_cands_ = 0;
  if (snap.rows() < 2 || f.count == 0) return 0;
  if (used_.size() < static_cast<size_t>(snap.rows())) {
    used_.resize(static_cast<size_t>(snap.rows()) * 2, 0);  // a map above its cap
  }
  const int n =
      uses_places() ? match_places(f, snap, epoch, pairs, cap) : match_all(f, snap, pairs, cap);
  return claim_rows(n, pairs);
}

int64_t Relocalizer::best_epoch(const Features& f, const KeyframeDatabase& places) {
  if (!uses_places() || f.count == 0) return -1;
  const int count = std::min(f.count, static_cast<int>(feat_node_.size()));
  vocabulary_->transform(f.desc.data, f.desc.step[0], count, bow_, voc_scratch_, nullptr,
                         params_.node_level, feat_node_.data());
  PlaceQueryParams qp;
  qp.max_candidates = 1;
  const int n = places.query(bow_, qp, query_scratch_, cands_.data(), 1);
  return n > 0 ? static_cast<int64_t>(cands_[0].epoch) : -1;
}

int Relocalizer::match_places(const Features& f, const MapSnapshot& snap, uint32_t epoch,
                              int* pairs, int cap) {
  if (!snap.places || snap.kf_row_start.size() != snap.kf_ids.size() + 1) return 0;
  const Vocabulary& voc = *vocabulary_;
  const int count = std::min(f.count, static_cast<int>(feat_node_.size()));
  // 1. Place recognition: the best keyframes of this map for the frame's words.
  voc.transform(f.desc.data, f.desc.step[0], count, bow_, voc_scratch_, nullptr, params_.node_level,
                feat_node_.data());
  PlaceQueryParams qp;
  qp.max_candidates = params_.candidates;
  qp.epoch = epoch;
  n_cands_ =
      snap.places->query(bow_, qp, query_scratch_, cands_.data(), static_cast<int>(cands_.size()));
  // 2. Their points (each row once), with the vocabulary node of each point's descriptor.
  int nr = 0;
  const int max_rows = static_cast<int>(rows_.size());
  for (int c = 0; c < n_cands_; ++c) {
    const auto it = std::find(snap.kf_ids.begin(), snap.kf_ids.end(), cands_[size_t(c)].keyframe);
    if (it == snap.kf_ids.end()) continue;
    const size_t ki = static_cast<size_t>(it - snap.kf_ids.begin());
    for (int k = snap.kf_row_start[ki]; k < snap.kf_row_start[ki + 1] && nr < max_rows; ++k) {
      const int r = snap.kf_rows[size_t(k)];
      if (used_[size_t(r)]) continue;
      used_[size_t(r)] = 1;
      rows_[size_t(nr++)] = r;
    }
  }
  for (int i = 0; i < nr; ++i) {
    used_[size_t(rows_[size_t(i)])] = 0;
    voc.transform(snap.desc.ptr<uint8_t>(rows_[size_t(i)]), params_.node_level,
                  &row_node_[size_t(i)]);
  }
  // 3. Direct index: the rows bucketed by node (counting sort).
  std::fill(bucket_start_.begin(), bucket_start_.end(), 0);
  for (int i = 0; i < nr; ++i) ++bucket_start_[size_t(row_node_[size_t(i)]) + 1];
  for (size_t b = 1; b < bucket_start_.size(); ++b) bucket_start_[b] += bucket_start_[b - 1];
  for (int i = 0; i < nr; ++i) {
    bucket_rows_[size_t(bucket_start_[size_t(row_node_[size_t(i)])]++)] = rows_[size_t(i)];
  }
  // bucket_start_[b] is now the end of bucket b, i.e. the start of bucket b + 1.
  // 4. Each feature against the rows under its node: 2-NN with the relocalization rule.
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kRelocalize, true);
  int n = 0;
  for (int j = 0; j < count && n < cap; ++j) {
    const size_t b = static_cast<size_t>(feat_node_[size_t(j)]);
    const int lo = b == 0 ? 0 : bucket_start_[b - 1], hi = bucket_start_[b];
    BestTwo best;
    const uint8_t* d = f.desc_ptr(j);
    for (int k = lo; k < hi; ++k) {
      const int r = bucket_rows_[size_t(k)];
      best.offer(hamming256(d, snap.desc.ptr<uint8_t>(r)), r);
    }
    if (!rule.accepts(best)) continue;
    pairs[2 * n] = j;
    pairs[2 * n + 1] = best.index;
    ++n;
  }
  return n;
}

int Relocalizer::match_all(const Features& f, const MapSnapshot& snap, int* pairs, int cap) {
  const int rows = snap.rows();
  const MatchRule& rule = fparams_.matching.rule(MatchPurpose::kRelocalize, binary_);
  int n = 0;
  if (binary_) {
    for (int j = 0; j < f.count && n < cap; ++j) {
      const BestTwo best = best_of_rows(f.desc_ptr(j), snap.desc, rows, true);
      if (!rule.accepts(best)) continue;
      pairs[2 * n] = j;
      pairs[2 * n + 1] = best.index;
      ++n;
    }
    return n;
  }
  if (!snap.kdtree) return 0;
  snap.kdtree->knnSearch(f.desc.rowRange(0, f.count), idx_, dist_, 2, cv::flann::SearchParams(32));
  for (int j = 0; j < f.count && n < cap; ++j) {
    // Paper Sec. 3: matched when c = ||p(x) - p(N1)|| / ||p(x) - p(N2)|| < 0.6.
    BestTwo best;
    best.d1 = std::sqrt(dist_.at<float>(j, 0));
    best.d2 = std::sqrt(dist_.at<float>(j, 1));
    const int r = idx_.at<int>(j, 0);
    best.index = r;
    if (r < 0 || r >= rows || best.d2 <= 0 || !rule.accepts(best)) continue;
    pairs[2 * n] = j;
    pairs[2 * n + 1] = r;
    ++n;
  }
  return n;
}

int Relocalizer::claim_rows(int n, int* pairs) {
  // One feature per map point: keep the first claim (rare duplicates are harmless for RANSAC
  // but would double-count inliers). used_ is all zero between calls.
  int k = 0;
  for (int i = 0; i < n; ++i) {
    const int r = pairs[2 * i + 1];
    if (used_[size_t(r)]) continue;
    used_[size_t(r)] = 1;
    pairs[2 * k] = pairs[2 * i];
    pairs[2 * k + 1] = r;
    ++k;
  }
  for (int i = 0; i < k; ++i) used_[size_t(pairs[2 * i + 1])] = 0;
  return k;
}

}  // namespace rdslam
