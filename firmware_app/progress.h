// Progress output of `rdslam replay`: a PipelineSink on the publisher thread that shows how
// far a recorded source got. On a terminal it redraws one bar in place (carriage returns, at
// most every 1% of the frames); when the stream is not a terminal (logs, CI, pipes) it
// writes a plain line every 10% instead, so that logs do not get one giant line of \r
// updates.
//
// Ownership: borrows `out`. Threads: on_frame() on the publisher thread only.
#pragma once

#include <cstdint>
#include <cstdio>

#include "firmware_app/pipeline.h"

namespace rdslam {

class ProgressSink : public PipelineSink {
 public:
  // `total` frames expected (<= 0: unknown, nothing is printed). `terminal`: redraw in place.
  ProgressSink(int64_t total, std::FILE* out, bool terminal)
      : total_(total), out_(out), terminal_(terminal) {}
  // For `out` = stderr etc.: terminal when isatty(fileno(out)).
  ProgressSink(int64_t total, std::FILE* out);
  void on_frame(const FrameResult& r) override;

 private:
  int64_t total_;
  std::FILE* out_;
  bool terminal_;
  int64_t done_ = 0;
  int64_t shown_ = -1;  // percentage last shown
};

}  // namespace rdslam
