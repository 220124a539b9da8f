#include "core/stages.h"

namespace rdslam {

const char* to_string(TrackingState s) {
  switch (s) {
    case TrackingState::kInitializing:
      return "INITIALIZING";
    case TrackingState::kTracking:
      return "TRACKING";
    case TrackingState::kLost:
      return "LOST";
    case TrackingState::kRelocalized:
      return "RELOCALIZED";
  }
  return "UNKNOWN";
}

}  // namespace rdslam
