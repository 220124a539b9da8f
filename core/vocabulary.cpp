#include "core/vocabulary.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <stdexcept>

#include "core/features.h"
#include "core/matching.h"

namespace rdslam {
namespace {

constexpr char kMagic[8] = {'R', 'D', 'S', 'L', 'V', 'O', 'C', '1'};
constexpr int kB = Vocabulary::kDescBytes;

uint64_t fnv1a(const uint8_t* p, size_t n) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

template <class T>
void put(std::vector<uint8_t>& out, T v) {
  const size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));
}

template <class T>
T get(const std::vector<uint8_t>& in, size_t& at) {
  T v;
  std::memcpy(&v, in.data() + at, sizeof(T));
  at += sizeof(T);
  return v;
}

// Index of the centre (of `kc`, kB bytes each) nearest to `x`; ties: the first.
int nearest(const uint8_t* x, const uint8_t* centres, int kc) {
  int best = 0, bd = 1 << 30;
  for (int c = 0; c < kc; ++c) {
    const int h = hamming256(x, centres + size_t(c) * kB);
    if (h < bd) {
      bd = h;
      best = c;
    }
  }
  return best;
}

// k-medians of the descriptors idx[0..n) (rows of `d`): k-means++ seeding, then assignment to
// the nearest centre and majority bits, until no assignment changes. Writes the centres
// (at most k; empty clusters are dropped) and each descriptor's cluster.
void kmedians(const uint8_t* d, const std::vector<int>& idx, int k, int iterations,
              std::mt19937_64& rng, std::vector<uint8_t>& centres, std::vector<int>& assign) {
  const size_t n = idx.size();
  centres.clear();
  // k-means++: the first centre at random, each next one with probability ~ squared distance.
  std::vector<double> dist2(n, 1e30);
  const uint8_t* first = d + size_t(idx[rng() % n]) * kB;
  centres.insert(centres.end(), first, first + kB);
  for (int c = 1; c < k; ++c) {
    const uint8_t* last = centres.data() + size_t(c - 1) * kB;
    double total = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const double h = hamming256(d + size_t(idx[i]) * kB, last);
      dist2[i] = std::min(dist2[i], h * h);
      total += dist2[i];
    }
    if (total <= 0.0) break;  // fewer distinct descriptors than k
    double r = std::uniform_real_distribution<double>(0.0, total)(rng);
    size_t pick = n - 1;
    for (size_t i = 0; i < n; ++i) {
      r -= dist2[i];
      if (r <= 0.0) {
        pick = i;
        break;
      }
    }
    const uint8_t* src = d + size_t(idx[pick]) * kB;
    centres.insert(centres.end(), src, src + kB);
  }
  int kc = static_cast<int>(centres.size() / kB);
  assign.assign(n, -1);
  std::vector<int> counts;
  for (int it = 0; it < iterations; ++it) {
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      const int best = nearest(d + size_t(idx[i]) * kB, centres.data(), kc);
      if (assign[i] != best) changed = true;
      assign[i] = best;
    }
    if (!changed) break;
    // Majority bit per cluster.
    counts.assign(size_t(kc) * 256, 0);
    std::vector<int> members(size_t(kc), 0);
    for (size_t i = 0; i < n; ++i) {
      const uint8_t* x = d + size_t(idx[i]) * kB;
      int* cnt = counts.data() + size_t(assign[i]) * 256;
      ++members[size_t(assign[i])];
      for (int b = 0; b < kB; ++b) {
        const unsigned v = x[b];
        for (int bit = 0; bit < 8; ++bit) cnt[b * 8 + bit] += (v >> bit) & 1u;
      }
    }
    std::vector<uint8_t> next;
    std::vector<int> remap(size_t(kc), -1);
    for (int c = 0; c < kc; ++c) {
      if (members[size_t(c)] == 0) continue;
      remap[size_t(c)] = static_cast<int>(next.size() / kB);
      const int* cnt = counts.data() + size_t(c) * 256;
      for (int b = 0; b < kB; ++b) {
        unsigned v = 0;
        for (int bit = 0; bit < 8; ++bit) {
          if (2 * cnt[b * 8 + bit] > members[size_t(c)]) v |= 1u << bit;
        }
        next.push_back(static_cast<uint8_t>(v));
      }
    }
    for (int& a : assign) a = remap[size_t(a)];
    centres.swap(next);
    kc = static_cast<int>(centres.size() / kB);
  }
  // Final assignment to the final centres.
  for (size_t i = 0; i < n; ++i) assign[i] = nearest(d + size_t(idx[i]) * kB, centres.data(), kc);
}

}  // namespace

std::string default_vocabulary_path() {
  if (const char* env = std::getenv("RDSLAM_VOCABULARY"); env != nullptr && *env != 0) return env;
  const std::string source = RDSLAM_VOCAB_SOURCE;
  if (std::ifstream(source).good()) return source;
  return RDSLAM_VOCAB_INSTALLED;
}

void BowVector::reserve(int n) {
  words.reserve(static_cast<size_t>(n));
  weights.reserve(static_cast<size_t>(n));
  if (words.size() < static_cast<size_t>(n)) {
    words.resize(static_cast<size_t>(n));
    weights.resize(static_cast<size_t>(n));
  }
}

Vocabulary Vocabulary::train(const std::vector<cv::Mat>& per_image, const TrainParams& p) {
  if (p.k < 2 || p.k > 64 || p.levels < 1 || p.levels > 8 || p.iterations < 1) {
    throw std::invalid_argument("vocabulary: k must be 2..64, levels 1..8, iterations >= 1");
  }
  std::vector<uint8_t> all;
  std::vector<int> image_of;
  for (size_t im = 0; im < per_image.size(); ++im) {
    const cv::Mat& m = per_image[im];
    if (m.empty()) continue;
    if (m.type() != CV_8U || m.cols != kB) {
      throw std::invalid_argument("vocabulary: training descriptors must be CV_8U, 32 columns");
    }
    for (int r = 0; r < m.rows; ++r) {
      all.insert(all.end(), m.ptr<uint8_t>(r), m.ptr<uint8_t>(r) + kB);
      image_of.push_back(static_cast<int>(im));
    }
  }
  if (all.empty()) throw std::invalid_argument("vocabulary: no training descriptors");
  Vocabulary v;
  v.k_ = p.k;
  v.levels_ = p.levels;
  std::mt19937_64 rng(p.seed);
  // Breadth first: the nodes of one level, each with its descriptors, produce the next level.
  struct Pending {
    int node;
    std::vector<int> idx;
  };
  v.first_child_.push_back(-1);
  v.children_.push_back(0);
  v.level_.push_back(0);
  v.word_.push_back(-1);
  v.desc_.resize(kB, 0);
  std::vector<Pending> cur(1);
  cur[0].node = 0;
  cur[0].idx.resize(image_of.size());
  for (size_t i = 0; i < image_of.size(); ++i) cur[0].idx[i] = static_cast<int>(i);
  std::vector<uint8_t> centres;
  std::vector<int> assign;
  for (int level = 1; level <= p.levels; ++level) {
    std::vector<Pending> next;
    for (Pending& pn : cur) {
      kmedians(all.data(), pn.idx, p.k, p.iterations, rng, centres, assign);
      const int kc = static_cast<int>(centres.size() / kB);
      v.first_child_[size_t(pn.node)] = v.nodes();
      v.children_[size_t(pn.node)] = static_cast<uint16_t>(kc);
      std::vector<std::vector<int>> members(static_cast<size_t>(kc));
      for (size_t i = 0; i < pn.idx.size(); ++i) members[size_t(assign[i])].push_back(pn.idx[i]);
      for (int c = 0; c < kc; ++c) {
        const int id = v.nodes();
        v.first_child_.push_back(-1);
        v.children_.push_back(0);
        v.level_.push_back(static_cast<uint16_t>(level));
        v.word_.push_back(-1);
        v.desc_.insert(v.desc_.end(), centres.begin() + c * kB, centres.begin() + (c + 1) * kB);
        // A cluster of one descriptor (or the last level) is a leaf.
        if (level < p.levels && members[size_t(c)].size() > 1) {
          next.push_back(Pending{id, std::move(members[size_t(c)])});
        }
      }
    }
    cur.swap(next);
  }
  // Words: the leaves, in node order.
  int words = 0;
  for (int i = 1; i < v.nodes(); ++i) {
    if (v.children_[size_t(i)] == 0) v.word_[size_t(i)] = words++;
  }
  // idf = ln(N / n_w) over the images that have descriptors.
  std::vector<int> last_image(size_t(words), -1), docs(size_t(words), 0);
  int images = 0;
  for (size_t im = 0, at = 0; im < per_image.size(); ++im) {
    const int rows = per_image[im].empty() ? 0 : per_image[im].rows;
    images += rows > 0;
    for (int r = 0; r < rows; ++r, ++at) {
      const int w = v.transform(all.data() + at * kB);
      if (last_image[size_t(w)] != int(im)) {
        last_image[size_t(w)] = int(im);
        ++docs[size_t(w)];
      }
    }
  }
  v.idf_.resize(size_t(words));
  for (int w = 0; w < words; ++w) {
    v.idf_[size_t(w)] =
        docs[size_t(w)] > 0 ? static_cast<float>(std::log(double(images) / docs[size_t(w)])) : 0.f;
  }
  v.validate("trained vocabulary");
  return v;
}

void Vocabulary::validate(const std::string& origin) {
  // Structure checks shared by load() and train(); fills the per-level indices.
  auto bad = [&](const std::string& what) {
    throw std::runtime_error("vocabulary " + origin + ": " + what);
  };
  const int n = nodes();
  if (n < 2 || children_[0] == 0) bad("empty tree");
  int words = 0;
  level_count_.assign(size_t(levels_) + 1, 0);
  for (int i = 0; i < n; ++i) {
    const int lv = level_[size_t(i)];
    if (lv > levels_) bad("node level above the tree depth");
    ++level_count_[size_t(lv)];
    if (children_[size_t(i)] == 0) {
      if (i == 0 || word_[size_t(i)] != words) bad("leaf words out of order");
      ++words;
      continue;
    }
    if (word_[size_t(i)] != -1) bad("an inner node has a word");
    const int f = first_child_[size_t(i)];
    if (f <= i || f + children_[size_t(i)] > n) bad("child index out of range");
    for (int c = f; c < f + children_[size_t(i)]; ++c) {
      if (level_[size_t(c)] != lv + 1) bad("child level inconsistent");
    }
  }
  if (words != static_cast<int>(idf_.size())) bad("word count does not match the weights");
}

int Vocabulary::nodes_at_level(int l) const {
  return l >= 0 && l <= levels_ ? level_count_[size_t(l)] : 0;
}

int Vocabulary::transform(const uint8_t* d, int node_level, int* node) const {
  int i = 0;
  while (children_[size_t(i)] > 0) {
    const int f = first_child_[size_t(i)];
    i = f + nearest(d, desc_.data() + size_t(f) * kB, children_[size_t(i)]);
    if (level_[size_t(i)] <= node_level && node) *node = i;
  }
  return word_[size_t(i)];
}

void Vocabulary::transform(const Features& f, BowVector& out, Scratch& scratch, int* word_of,
                           int node_level, int* node_of) const {
  transform(f.desc.data, f.desc.step[0], f.count, out, scratch, word_of, node_level, node_of);
}

void Vocabulary::transform(const uint8_t* desc, size_t stride, int count, BowVector& out,
                           Scratch& scratch, int* word_of, int node_level, int* node_of) const {
  std::vector<uint64_t>& key = scratch.key;
  key.resize(static_cast<size_t>(count));  // within the reserved capacity after warm-up
  for (int j = 0; j < count; ++j) {
    const int w = transform(desc + size_t(j) * stride, node_level, node_of ? node_of + j : nullptr);
    if (word_of) word_of[j] = w;
    key[size_t(j)] = (uint64_t(uint32_t(w)) << 32) | uint32_t(j);
  }
  std::sort(key.begin(), key.end());
  out.reserve(count);
  // tf-idf: weight = (n_w / count) * idf_w, then L1-normalised (DBoW2 TF_IDF, L1 norm).
  int n = 0;
  double sum = 0.0;
  for (size_t a = 0; a < key.size();) {
    const int w = static_cast<int>(key[a] >> 32);
    size_t b = a;
    while (b < key.size() && static_cast<int>(key[b] >> 32) == w) ++b;
    const float weight = float(b - a) / float(count) * idf_[size_t(w)];
    if (weight > 0.f) {
      out.words[size_t(n)] = w;
      out.weights[size_t(n)] = weight;
      sum += weight;
      ++n;
    }
    a = b;
  }
  out.size = n;
  if (sum > 0.0) {
    for (int i = 0; i < n; ++i) out.weights[size_t(i)] = float(out.weights[size_t(i)] / sum);
  }
}

void Vocabulary::serialise(std::vector<uint8_t>& out) const {
  out.clear();
  uint64_t magic;
  std::memcpy(&magic, kMagic, 8);
  put<uint64_t>(out, magic);
  put<uint32_t>(out, uint32_t(k_));
  put<uint32_t>(out, uint32_t(levels_));
  put<uint32_t>(out, uint32_t(nodes()));
  put<uint32_t>(out, uint32_t(words()));
  for (int i = 0; i < nodes(); ++i) {
    put<int32_t>(out, first_child_[size_t(i)]);
    put<uint16_t>(out, children_[size_t(i)]);
    put<uint16_t>(out, level_[size_t(i)]);
    put<int32_t>(out, word_[size_t(i)]);
    const size_t at = out.size();
    out.resize(at + kB);
    std::memcpy(out.data() + at, desc_.data() + size_t(i) * kB, kB);
  }
  for (float w : idf_) put<float>(out, w);
}

uint64_t Vocabulary::checksum() const {
  std::vector<uint8_t> bytes;
  serialise(bytes);
  return fnv1a(bytes.data(), bytes.size());
}

void Vocabulary::save(const std::string& path) const {
  std::vector<uint8_t> bytes;
  serialise(bytes);
  put<uint64_t>(bytes, fnv1a(bytes.data(), bytes.size()));
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("vocabulary " + path + ": cannot open for writing");
  f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!f) throw std::runtime_error("vocabulary " + path + ": write error");
}

Vocabulary Vocabulary::load(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    throw std::runtime_error("vocabulary " + path +
                             ": cannot open (missing? `rdslam vocab train` makes one, "
                             "docs/place_recognition.md)");
  }
  std::vector<uint8_t> in((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  auto bad = [&](const std::string& what) {
    throw std::runtime_error("vocabulary " + path + ": " + what);
  };
  constexpr size_t kHeader = 8 + 4 * 4, kNode = 4 + 2 + 2 + 4 + kB;
  if (in.size() < kHeader + 8) bad("truncated (" + std::to_string(in.size()) + " bytes)");
  if (std::memcmp(in.data(), kMagic, 8) != 0) bad("not an rdslam vocabulary (bad magic)");
  size_t at = 8;
  Vocabulary v;
  v.k_ = static_cast<int>(get<uint32_t>(in, at));
  v.levels_ = static_cast<int>(get<uint32_t>(in, at));
  const uint32_t nodes = get<uint32_t>(in, at), words = get<uint32_t>(in, at);
  if (v.k_ < 2 || v.k_ > 64 || v.levels_ < 1 || v.levels_ > 8 || nodes > (1u << 26) ||
      words > nodes) {
    bad("implausible header");
  }
  const size_t expect = kHeader + size_t(nodes) * kNode + size_t(words) * 4 + 8;
  if (in.size() != expect) {
    bad("size " + std::to_string(in.size()) + " bytes, header says " + std::to_string(expect) +
        " (truncated or corrupt)");
  }
  uint64_t stored;
  std::memcpy(&stored, in.data() + expect - 8, 8);
  if (fnv1a(in.data(), expect - 8) != stored) bad("checksum mismatch (corrupt file)");
  v.first_child_.resize(nodes);
  v.children_.resize(nodes);
  v.level_.resize(nodes);
  v.word_.resize(nodes);
  v.desc_.resize(size_t(nodes) * kB);
  for (uint32_t i = 0; i < nodes; ++i) {
    v.first_child_[i] = get<int32_t>(in, at);
    v.children_[i] = get<uint16_t>(in, at);
    v.level_[i] = get<uint16_t>(in, at);
    v.word_[i] = get<int32_t>(in, at);
    std::memcpy(v.desc_.data() + size_t(i) * kB, in.data() + at, kB);
    at += kB;
  }
  v.idf_.resize(words);
  for (uint32_t w = 0; w < words; ++w) v.idf_[w] = get<float>(in, at);
  v.validate(path);
  return v;
}

}  // namespace rdslam
