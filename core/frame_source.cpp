#include "core/frame_source.h"

#include <ctime>

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

int64_t mono_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

}  // namespace rdslam
