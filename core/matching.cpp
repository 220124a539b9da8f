#include "core/matching.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace rdslam {

const char* to_string(MatchPurpose p) {
  switch (p) {
    case MatchPurpose::kMotion:
      return "motion";
    case MatchPurpose::kLocalMap:
      return "local";
    case MatchPurpose::kInit:
      return "init";
    case MatchPurpose::kTriangulate:
      return "triangulate";
    case MatchPurpose::kFuse:
      return "fuse";
    case MatchPurpose::kRelocalize:
      return "reloc";
  }
  return "unknown";
}

void MatchingParams::visit(ParamVisitor& v) {
  static const char* const kDoc[kMatchPurposes] = {"motion-model search (tracker)",
                                                   "map-point projection search (tracker)",
                                                   "two-frame initialisation",
                                                   "triangulation along epipolar lines (mapper)",
                                                   "map point fused into a keyframe (mapper)",
                                                   "global relocalization search"};
  static const char* const kMode[2] = {"orb", "sift"};
  static const char* const kUnit[2] = {"max Hamming distance (of 256)", "max L2 distance"};
  // Keys and help texts live as long as the process (ParamVisitor takes C strings); built once
  // (thread-safe static initialisation), two entries per rule in the order visited below.
  static const std::vector<std::string> text = [] {
    std::vector<std::string> t;
    for (int m = 0; m < 2; ++m) {
      for (int p = 0; p < kMatchPurposes; ++p) {
        const std::string base = std::string(kMode[m]) + "_" + to_string(MatchPurpose(p)) + "_";
        t.insert(t.end(), {base + "max_distance", std::string(kUnit[m]) + ": " + kDoc[p],
                           base + "ratio", std::string("2-NN ratio (1 = off): ") + kDoc[p]});
      }
    }
    return t;
  }();
  MatchRule* const rules[2] = {orb, sift};
  const double max_hi[2] = {256.0, 1000.0};
  size_t k = 0;
  for (int m = 0; m < 2; ++m) {
    for (int p = 0; p < kMatchPurposes; ++p, k += 4) {
      v.field(text[k].c_str(), rules[m][p].max_distance, 1.0, max_hi[m], text[k + 1].c_str());
      v.field(text[k + 2].c_str(), rules[m][p].ratio, 0.1, 1.0, text[k + 3].c_str());
    }
  }
}

double descriptor_distance(const uint8_t* a, const uint8_t* b, bool binary) {
  if (binary) return hamming256(a, b);
  const float* x = reinterpret_cast<const float*>(a);
  const float* y = reinterpret_cast<const float*>(b);
  float s = 0.f;
  for (int i = 0; i < 128; ++i) {
    const float d = x[i] - y[i];
    s += d * d;
  }
  return std::sqrt(static_cast<double>(s));
}

BestTwo best_of_rows(const uint8_t* d, const cv::Mat& desc, int rows, bool binary) {
  BestTwo best;
  for (int r = 0; r < rows; ++r)
    best.offer(descriptor_distance(d, desc.ptr<uint8_t>(r), binary), r);
  return best;
}

int predict_level(double max_dist, double dist, double log_scale_factor, int levels) {
  const int lvl = static_cast<int>(std::ceil(std::log(max_dist / 1.2 / dist) / log_scale_factor));
  return std::max(0, std::min(levels - 1, lvl));
}

void ClaimTable::reset(int queries, int targets) {
  target_of_.assign(static_cast<size_t>(queries), -1);
  query_of_.assign(static_cast<size_t>(targets), -1);
  dist_.assign(static_cast<size_t>(targets), 1e30);
}

int ClaimTable::matched() const {
  return static_cast<int>(
      std::count_if(target_of_.begin(), target_of_.end(), [](int t) { return t >= 0; }));
}

}  // namespace rdslam
