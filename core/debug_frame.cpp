#include "core/debug_frame.h"

namespace rdslam {

const char* to_string(DebugFeatureKind k) {
  switch (k) {
    case DebugFeatureKind::kUnmatched:
      return "unmatched";
    case DebugFeatureKind::kInlier:
      return "inlier";
    case DebugFeatureKind::kRejectedRobust:
      return "rejected-robust";
    case DebugFeatureKind::kRejectedRefine:
      return "rejected-refine";
    case DebugFeatureKind::kUnsupported:
      return "unsupported";
  }
  return "unknown";
}

int count_features(const DebugFrame& d, DebugFeatureKind k) {
  int n = 0;
  for (const DebugFeature& f : d.features) n += f.kind == k;
  return n;
}

}  // namespace rdslam
