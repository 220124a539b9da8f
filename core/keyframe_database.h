// Place recognition: a database of keyframes' bag-of-words vectors (core/vocabulary.h) with
// an inverted index word -> keyframes, as DBoW2's database and ORB-SLAM2's KeyFrameDatabase.
// A query scores only the keyframes that share a word with the frame (DBoW2's L1 score,
// sum over shared words of min(q_w, v_w) for L1-normalised vectors, in [0, 1]), keeps those
// sharing at least `min_common_ratio` x the most shared words (ORB-SLAM2's 0.8) and returns
// the best `max_candidates` as (map epoch, keyframe id, score): a database may hold the
// keyframes of several maps (epochs), and a query may be limited to one epoch.
//
// Two types: the mapper edits a KeyframeDatabaseBuilder (add when a keyframe is accepted,
// remove when it goes) and, at a publish, build() turns it into an immutable KeyframeDatabase
// (flat arrays, the inverted index in CSR form) that travels to the tracker inside the
// MapSnapshot (core/match_index.h); build() returns the previous one when nothing changed.
//
// Cost of a query: one pass over the inverted lists of the frame's words (at most
// words x keyframes entries, bounded by the map's keyframe cap) and a partial sort of the
// keyframes that share a word; no allocation once the caller's PlaceQueryScratch has the
// database's size (reserve it for mapper.max_keyframes).
//
// Ownership/threads: the builder is the mapper's (mapper thread only); a built database is
// immutable and shared (any thread may query it with its own scratch).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "core/vocabulary.h"

namespace rdslam {

struct PlaceCandidate {
  uint32_t epoch = 0;
  int keyframe = -1;  // keyframe id in that epoch's map
  float score = 0.f;  // L1 score in [0, 1]
  int common_words = 0;
};

struct PlaceQueryParams {
  int max_candidates = 3;
  double min_common_ratio = 0.8;  // of the most words any keyframe shares with the query
  int64_t epoch = -1;             // >= 0: only keyframes of this map epoch
};

// Per-entry accumulators of one query; grows to the largest database queried (reserve() it).
struct PlaceQueryScratch {
  std::vector<int> common;
  std::vector<float> score;
  std::vector<int> touched;
  void reserve(int entries);
};

class KeyframeDatabase {
 public:
  int size() const { return static_cast<int>(kf_.size()); }
  uint32_t epoch(int entry) const { return epoch_[size_t(entry)]; }
  int keyframe(int entry) const { return kf_[size_t(entry)]; }
  // Writes at most min(p.max_candidates, cap) candidates, best score first; returns their number.
  int query(const BowVector& q, const PlaceQueryParams& p, PlaceQueryScratch& scratch,
            PlaceCandidate* out, int cap) const;

 private:
  friend class KeyframeDatabaseBuilder;
  std::vector<uint32_t> epoch_;
  std::vector<int> kf_;
  std::vector<int> word_start_;  // words + 1
  std::vector<int> post_entry_;  // inverted lists, CSR
  std::vector<float> post_weight_;
};

class KeyframeDatabaseBuilder {
 public:
  explicit KeyframeDatabaseBuilder(int words) : words_(words) {}
  // Adds (or replaces) the vector of keyframe `kf` of map `epoch`.
  void add(uint32_t epoch, int kf, const BowVector& v);
  void remove(uint32_t epoch, int kf);
  // Removes the keyframes of `epoch` for which keep(kf) is false.
  template <class Keep>
  void retain(uint32_t epoch, Keep&& keep) {
    for (auto it = entries_.lower_bound({epoch, -1});
         it != entries_.end() && it->first.first == epoch;) {
      if (keep(it->first.second)) {
        ++it;
      } else {
        it = entries_.erase(it);
        built_.reset();
      }
    }
  }
  void clear();
  int size() const { return static_cast<int>(entries_.size()); }
  bool contains(uint32_t epoch, int kf) const { return entries_.count({epoch, kf}) > 0; }
  // The immutable database of the current entries (the same object while nothing changed).
  std::shared_ptr<const KeyframeDatabase> build();

 private:
  int words_;
  std::map<std::pair<uint32_t, int>, std::vector<std::pair<int, float>>> entries_;
  std::shared_ptr<const KeyframeDatabase> built_;
};

}  // namespace rdslam
