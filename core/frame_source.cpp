#include "core/frame_source.h"

namespace rdslam {

const char* to_string(SourceStatus s) {
  switch (s) {
    case SourceStatus::kOk:
      return "ok";
    case SourceStatus::kEndOfStream:
      return "end-of-stream";
    case SourceStatus::kTimeout:
      return "timeout";
    case SourceStatus::kFault:
      return "fault";
  }
  return "unknown";
}

}  // namespace rdslam
