// Fault injection for replays (`rdslam replay SOURCE --inject SPEC`, issue 25): a
// FrameSource decorator that damages chosen frames of a recorded source the way a cheap
// camera, a bad USB link or a broken recording does, so tests can check that rdslam
// survives, counts each fault (rdslam.status_t, the replay report) and tracks again after.
//
// SPEC is a comma-separated list of KIND@FIRST[-LAST][:VALUE] items; FIRST..LAST (inclusive,
// 0-based) number the frames the inner source delivers, in order. Kinds:
//   corrupt     the frame is JPEG-encoded, 48 bytes of its entropy-coded data are
//               overwritten, and it is decoded again through the MJPEG decoder (strict, as
//               V4L2 cameras): rejected as a source fault, or delivered garbled when
//               libjpeg does not notice
//   truncate    JPEG-encoded, cut to 60% of its bytes (an interrupted USB transfer),
//               decoded again: a source fault
//   zero        a zero-size image (0 x 0)
//   black       all pixels 0;  saturated: all pixels 255
//   exposure    pixel values scaled by VALUE (required; 0.05..20), saturating
//   stamp_back  stamp one frame interval before the last good stamp (a clock step back)
//   dup_stamp   stamp equal to the last good stamp (a frame delivered twice)
//   drop        the frames are read and not delivered (counted as skipped by the source)
//   unplug      the camera disappears: the first frame of the range is a source fault, the
//               others time out; the first frame after the range comes back with one reopen
// Example: corrupt@40-45,black@60-70,drop@80-95,stamp_back@100,exposure@120-160:3,unplug@170-200
//
// Ownership: the returned source owns the inner source, an encode buffer and a decoder.
// Threads: as FrameSource (one reader thread). Only damaged frames allocate (JPEG encoding,
// a zero-size image's slot); the others pass through untouched.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/frame_source.h"

namespace rdslam {

enum class FaultKind : uint8_t {
  kCorrupt,
  kTruncate,
  kZero,
  kBlack,
  kSaturated,
  kExposure,
  kStampBack,
  kDupStamp,
  kDrop,
  kUnplug,
};
const char* to_string(FaultKind k);

struct FaultSpan {
  FaultKind kind = FaultKind::kBlack;
  int64_t first = 0, last = 0;  // inclusive frame numbers of the inner source
  double value = 1.0;           // exposure gain
};

// Parses SPEC (grammar above). Throws std::invalid_argument naming the bad item.
std::vector<FaultSpan> parse_fault_spec(const std::string& spec);

// Throws std::runtime_error (start-up boundary) when `inner` is null. An empty plan returns
// `inner` itself.
std::unique_ptr<FrameSource> make_fault_injection_source(std::unique_ptr<FrameSource> inner,
                                                         std::vector<FaultSpan> plan);

}  // namespace rdslam
