// Endurance replay: a recorded sequence played N times in a row (`rdslam replay --loop N`),
// for soak tests of a system meant to run for days (bounded map, no growth over time).
//
// make_looped_source() reads the whole inner source once, at start-up, into a frame cache
// allocated up front (frame_count x frame size; refused above `max_cache_bytes`), then serves
// frame i of the looped sequence from cache slot i mod n. Pass k's stamps are the inner
// stamps shifted by k * (duration + one frame period), so time keeps increasing and the
// ground truth (when the inner source has one) is the inner trajectory repeated with the
// same shifts. At every loop boundary the camera jumps back to its first pose and the scene
// to its first state: the tracker must relocalize and the map must absorb the change again.
// The result is a ReplaySource, so `speed` paces it like any recording (0: lossless).
//
// Ownership: the returned source owns the cache and the inner source's metadata (the inner
// source itself is closed after caching). Threads: as FrameSource (one reader thread).
#pragma once

#include <cstddef>
#include <memory>

#include "core/frame_source.h"

namespace rdslam {

// `inner` must be a recorded source (not live) with a known frame count, opened unpaced
// (speed 0). Throws std::runtime_error (start-up boundary) when `loops` < 1, the source is
// live, empty, or its cache would exceed `max_cache_bytes`.
std::unique_ptr<FrameSource> make_looped_source(std::unique_ptr<FrameSource> inner, int loops,
                                                double speed,
                                                size_t max_cache_bytes = size_t{2} << 30);

}  // namespace rdslam
