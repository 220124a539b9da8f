// Fast-forward replay: every N-th frame of a recorded source (`rdslam replay --every N`).
//
// make_decimated_source() reads the inner source and keeps frames 0, N, 2N, ...; the others
// are read and dropped. Stamps, dataset indices, camera and ground truth are the inner
// source's, unchanged, so a 10 Hz sequence with N = 2 is a 5 Hz sequence with twice the
// motion per frame, evaluated against the same ground truth. Frame::seq is renumbered
// 0, 1, 2, ... over the kept frames (it never repeats); info() reports the kept frame count
// and the nominal rate divided by N. Pacing is the inner source's: a paced replay delivers
// each kept frame at its recorded stamp.
//
// Ownership: the returned source owns the inner source. Threads: as FrameSource (one reader
// thread). read() does not allocate once the caller's frame has the source's size.
#pragma once

#include <memory>

#include "core/frame_source.h"

namespace rdslam {

// Throws std::runtime_error (start-up boundary) when `inner` is null or live, or `every` < 1.
// every == 1 returns `inner` itself.
std::unique_ptr<FrameSource> make_decimated_source(std::unique_ptr<FrameSource> inner, int every);

}  // namespace rdslam
