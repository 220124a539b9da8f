// A visual vocabulary for ORB descriptors (bag of words, Nister & Stewenius 2006; DBoW2's
// design, Galvez-Lopez & Tardos 2012): a tree of k-medians clusters of 256-bit descriptors,
// `levels` deep with at most `k` children per node; its leaves are the words. A descriptor's
// word is found by descending from the root to the child with the smallest Hamming distance
// (ties: the first child). Each word has an inverse document frequency, idf = ln(N / n_w) over
// the N training images, n_w of which contain the word; a set of features becomes a sparse
// tf-idf vector (BowVector, L1-normalised, DBoW2's TF_IDF weighting and L1 score).
//
// Training: hierarchical k-medians (k-means++ seeding, majority bit per cluster) over the
// descriptors of training images (`rdslam vocab train`, docs/place_recognition.md); the
// repository's vocabulary data/vocab/orb_k10l4.bin is made from synthetic scenes and OpenCV's
// vtest.avi, never from a dataset whose licence forbids derivatives (KITTI).
//
// File format (little-endian): "RDSLVOC1", u32 k, u32 levels, u32 nodes, u32 words, then per
// node i32 first_child, u16 children, u16 level, i32 word (-1: inner), 32 descriptor bytes;
// then f32 idf per word; then u64 FNV-1a checksum of every byte before it.
//
// Ownership: a Vocabulary is immutable after load()/train(); share it by shared_ptr<const>.
// Threads: any thread may call the const members concurrently (tracker and mapper do).
// transform() does not allocate when `out` and the scratch have reached the feature count.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rdslam {

struct Features;

// A sparse bag-of-words vector: `size` entries with ascending word ids, weights summing to 1.
// Buffers grow to the largest vector once and are reused.
struct BowVector {
  int size = 0;
  std::vector<int> words;
  std::vector<float> weights;
  void reserve(int n);
  void clear() { size = 0; }
};

// The vocabulary file used when tracker.reloc_vocabulary is empty: $RDSLAM_VOCABULARY if set,
// else data/vocab/orb_k10l4.bin of the source tree when it exists, else the installed copy
// (<prefix>/share/rdslam/vocab/orb_k10l4.bin).
std::string default_vocabulary_path();

class Vocabulary {
 public:
  static constexpr int kDescBytes = 32;  // ORB (256 bits)

  struct TrainParams {
    int k = 10;           // children per node
    int levels = 4;       // depth (words <= k^levels)
    int iterations = 12;  // k-medians iterations per node (at most)
    uint64_t seed = 1;    // k-means++ seeding
  };
  // Hierarchical k-medians over the rows of each image's CV_8U 32-column descriptor matrix;
  // idf from the images. Throws std::invalid_argument on bad parameters or no descriptors.
  static Vocabulary train(const std::vector<cv::Mat>& per_image, const TrainParams& params);
  // Throws std::runtime_error naming the path and what is wrong (missing, truncated, bad magic,
  // checksum mismatch, inconsistent tree).
  static Vocabulary load(const std::string& path);
  // Throws std::runtime_error when the file cannot be written.
  void save(const std::string& path) const;

  int k() const { return k_; }
  int levels() const { return levels_; }
  int words() const { return static_cast<int>(idf_.size()); }
  int nodes() const { return static_cast<int>(level_.size()); }
  // Nodes at tree level `l` (root 0, its children 1, ...).
  int nodes_at_level(int l) const;
  uint64_t checksum() const;  // FNV-1a of the serialised tree and weights
  float idf(int word) const { return idf_[static_cast<size_t>(word)]; }

  // The word of descriptor `d`; with `node` non-null also the index (0..nodes()) of its
  // ancestor at level `node_level` (1..levels; a leaf above that level stands for itself):
  // DBoW2's direct index, which limits descriptor matching to features under one node.
  int transform(const uint8_t* d, int node_level = 0, int* node = nullptr) const;

  struct Scratch {
    std::vector<uint64_t> key;  // (word << 32 | feature) per feature, sorted
    void reserve(int n) { key.reserve(static_cast<size_t>(n)); }
  };
  // The tf-idf vector of the first `count` descriptors of `f` (ORB); per feature its word
  // (`word_of`, may be null) and its level-`node_level` node (`node_of`, may be null).
  void transform(const Features& f, BowVector& out, Scratch& scratch, int* word_of = nullptr,
                 int node_level = 0, int* node_of = nullptr) const;
  // Same for `count` descriptors of 32 bytes each, `stride` bytes apart.
  void transform(const uint8_t* desc, size_t stride, int count, BowVector& out, Scratch& scratch,
                 int* word_of = nullptr, int node_level = 0, int* node_of = nullptr) const;

 private:
  void serialise(std::vector<uint8_t>& out) const;
  void validate(const std::string& origin);  // also fills level_count_

  int k_ = 0, levels_ = 0;
  // Per node (breadth first; node 0 the root, without a descriptor).
  std::vector<int> first_child_;
  std::vector<uint16_t> children_, level_;
  std::vector<int> word_;  // leaf: word id; inner node: -1
  std::vector<uint8_t> desc_;
  std::vector<float> idf_;
  std::vector<int> level_count_;
};

}  // namespace rdslam
