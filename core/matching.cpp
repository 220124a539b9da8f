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
  // Keys and help texts live as long as the process (ParamVisitor takes C strings).
  static std::vector<std::string> keys, docs;
  if (keys.empty()) {
    for (const char* mode : {"orb", "sift"}) {
      for (int p = 0; p < kMatchPurposes; ++p) {
        const std::string base = std::string(mode) + "_" + to_string(MatchPurpose(p));
        keys.push_back(base + "_max_distance");
        docs.push_back(std::string(mode == std::string("orb") ? "max Hamming distance (of 256)"
                                                              : "max L2 distance") +
                       ": " + kDoc[p]);
        keys.push_back(base + "_ratio");
        docs.push_back(std::string("2-NN ratio (1 = off): ") + kDoc[p]);
      }
    }
  }
  size_t k = 0;
  for (MatchRule* rules : {orb, sift}) {
    const double max_hi = rules == orb ? 256.0 : 1000.0;
    for (int p = 0; p < kMatchPurposes; ++p, k += 2) {
      v.field(keys[k].c_str(), rules[p].max_distance, 1.0, max_hi, docs[k].c_str());
      v.field(keys[k + 1].c_str(), rules[p].ratio, 0.1, 1.0, docs[k + 1].c_str());
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
