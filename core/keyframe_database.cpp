#include "core/keyframe_database.h"

#include <algorithm>

namespace rdslam {

void PlaceQueryScratch::reserve(int entries) {
  if (common.size() < static_cast<size_t>(entries)) {
    common.resize(static_cast<size_t>(entries), 0);
    score.resize(static_cast<size_t>(entries), 0.f);
  }
  touched.reserve(static_cast<size_t>(entries));
}

int KeyframeDatabase::query(const BowVector& q, const PlaceQueryParams& p, PlaceQueryScratch& s,
                            PlaceCandidate* out, int cap) const {
  s.reserve(size());  // no allocation once reserved for the database's size
  s.touched.clear();
  // One pass over the inverted lists of the query's words: shared words and the L1 score.
  const int words = static_cast<int>(word_start_.size()) - 1;
  for (int i = 0; i < q.size; ++i) {
    const int w = q.words[size_t(i)];
    if (w < 0 || w >= words) continue;
    const float qw = q.weights[size_t(i)];
    for (int k = word_start_[size_t(w)]; k < word_start_[size_t(w) + 1]; ++k) {
      const int e = post_entry_[size_t(k)];
      if (p.epoch >= 0 && epoch_[size_t(e)] != uint32_t(p.epoch)) continue;
      if (s.common[size_t(e)]++ == 0) s.touched.push_back(e);
      s.score[size_t(e)] += std::min(qw, post_weight_[size_t(k)]);
    }
  }
  int max_common = 0;
  for (int e : s.touched) max_common = std::max(max_common, s.common[size_t(e)]);
  const int min_common = static_cast<int>(p.min_common_ratio * max_common);
  // Keep the entries sharing enough words (in place), best score first; reset the rest.
  size_t kept = 0;
  for (int e : s.touched) {
    if (s.common[size_t(e)] >= min_common && s.common[size_t(e)] > 0) {
      s.touched[kept++] = e;
    } else {
      s.common[size_t(e)] = 0;
      s.score[size_t(e)] = 0.f;
    }
  }
  const int n = std::min<int>({static_cast<int>(kept), p.max_candidates, cap});
  auto better = [&](int a, int b) {
    const float sa = s.score[size_t(a)], sb = s.score[size_t(b)];
    return sa != sb ? sa > sb : a < b;
  };
  std::partial_sort(s.touched.begin(), s.touched.begin() + n, s.touched.begin() + long(kept),
                    better);
  for (int i = 0; i < n; ++i) {
    const int e = s.touched[size_t(i)];
    out[i] =
        PlaceCandidate{epoch_[size_t(e)], kf_[size_t(e)], s.score[size_t(e)], s.common[size_t(e)]};
  }
  for (size_t i = 0; i < kept; ++i) {
    const int e = s.touched[i];
    s.common[size_t(e)] = 0;
    s.score[size_t(e)] = 0.f;
  }
  s.touched.clear();
  return n;
}

void KeyframeDatabaseBuilder::add(uint32_t epoch, int kf, const BowVector& v) {
  std::vector<std::pair<int, float>>& e = entries_[{epoch, kf}];
  e.resize(static_cast<size_t>(v.size));
  for (int i = 0; i < v.size; ++i) e[size_t(i)] = {v.words[size_t(i)], v.weights[size_t(i)]};
  built_.reset();
}

void KeyframeDatabaseBuilder::remove(uint32_t epoch, int kf) {
  if (entries_.erase({epoch, kf}) > 0) built_.reset();
}

void KeyframeDatabaseBuilder::clear() {
  if (entries_.empty()) return;
  entries_.clear();
  built_.reset();
}

std::shared_ptr<const KeyframeDatabase> KeyframeDatabaseBuilder::build() {
  if (built_) return built_;
  auto db = std::make_shared<KeyframeDatabase>();
  db->word_start_.assign(static_cast<size_t>(words_) + 1, 0);
  for (const auto& [key, v] : entries_) {
    db->epoch_.push_back(key.first);
    db->kf_.push_back(key.second);
    for (const auto& [w, weight] : v) {
      if (w >= 0 && w < words_) ++db->word_start_[size_t(w) + 1];
    }
  }
  for (int w = 0; w < words_; ++w) db->word_start_[size_t(w) + 1] += db->word_start_[size_t(w)];
  const size_t total = static_cast<size_t>(db->word_start_.back());
  db->post_entry_.resize(total);
  db->post_weight_.resize(total);
  std::vector<int> fill(db->word_start_.begin(), db->word_start_.end() - 1);
  int e = 0;
  for (const auto& kv : entries_) {
    for (const auto& [w, weight] : kv.second) {
      if (w < 0 || w >= words_) continue;
      const int at = fill[size_t(w)]++;
      db->post_entry_[size_t(at)] = e;
      db->post_weight_[size_t(at)] = weight;
    }
    ++e;
  }
  built_ = std::move(db);
  return built_;
}

}  // namespace rdslam
