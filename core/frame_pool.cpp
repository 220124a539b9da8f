#include "core/frame_pool.h"

#include <stdexcept>
#include <string>

namespace rdslam {

FramePool::FramePool(int slots, int width, int height, PixelFormat format)
    : free_(slots > 0 ? static_cast<uint32_t>(slots) : 1u) {
  if (slots < 1) throw std::invalid_argument("frame pool: slots must be >= 1");
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("frame pool: frame size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is not positive");
  }
  const int type = format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  frames_.resize(static_cast<size_t>(slots));
  for (int i = 0; i < slots; ++i) {
    // Touch every page now so the first frames do not pay for page faults.
    frames_[i].image = cv::Mat(height, width, type, cv::Scalar::all(0));
    frames_[i].format = format;
    free_.try_push(static_cast<uint32_t>(i));
  }
}

bool FramePool::wait_acquire(uint32_t& slot, int timeout_ms) {
  if (free_.try_pop(slot)) return true;
  const uint32_t ticket = released_.ticket();
  if (free_.try_pop(slot)) return true;
  released_.wait(ticket, timeout_ms);
  return free_.try_pop(slot);
}

bool FramePool::release(uint32_t slot) {
  if (slot >= frames_.size()) return false;
  // The free ring holds every slot at most once, so it cannot be full.
  if (!free_.try_push(slot)) return false;
  released_.ring();
  return true;
}

}  // namespace rdslam
