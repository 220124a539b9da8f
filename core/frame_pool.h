// Fixed pool of preallocated frames shared by the capture and tracker threads. Rings pass
// slot indices (uint32_t), never images: a frame is written once by the source, read in
// place by the tracker, then its slot comes back to the pool.
//
// Every slot is always in exactly one place: the pool's free list, the capture thread's
// hands, the capture->tracker ring, or the tracker's hands. The free list is an SPSC ring
// (producer: the releasing thread, consumer: the acquiring thread), so acquire() and
// release() need no lock and never allocate.
//
// Ownership: the pool owns the Frame buffers (allocated in the constructor, start-up only).
// Threads: acquire()/wait_acquire() from ONE thread (capture), release() from ONE thread
// (tracker); frame(i) by whichever thread currently holds slot i.
#pragma once

#include <cstdint>
#include <vector>

#include "core/frame_source.h"
#include "core/spsc_ring.h"

namespace rdslam {

class FramePool {
 public:
  // Allocates `slots` frames of width x height in `format` (Gray8 or Bgr8). Throws
  // std::invalid_argument for slots < 1 or a non-positive size (start-up boundary).
  FramePool(int slots, int width, int height, PixelFormat format);
  FramePool(const FramePool&) = delete;
  FramePool& operator=(const FramePool&) = delete;

  int slots() const { return static_cast<int>(frames_.size()); }
  Frame& frame(uint32_t slot) { return frames_[slot]; }
  const Frame& frame(uint32_t slot) const { return frames_[slot]; }

  // Acquiring thread: a free slot; false when every slot is in use.
  bool try_acquire(uint32_t& slot) { return free_.try_pop(slot); }
  // Acquiring thread: like try_acquire, but waits up to `timeout_ms` for a release.
  bool wait_acquire(uint32_t& slot, int timeout_ms);
  // Releasing thread: give a slot back (wakes a waiting acquirer). Returns false, and
  // changes nothing, for an index that is not a slot of this pool.
  bool release(uint32_t slot);

  // Free slots right now (exact only when both threads are idle).
  uint32_t free_slots() const { return free_.size_approx(); }

 private:
  std::vector<Frame> frames_;
  SpscRing<uint32_t> free_;
  Doorbell released_;
};

}  // namespace rdslam
