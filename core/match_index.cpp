#include "core/match_index.h"

namespace rdslam {

void MatchIndex::publish(std::shared_ptr<const MapSnapshot> snap) {
  std::shared_ptr<const MapSnapshot> old;
  {
    std::lock_guard<std::mutex> lock(swap_mutex_);
    old = std::move(active_);
    active_ = std::move(snap);
  }
  version_.fetch_add(1, std::memory_order_release);
  // Keep the old snapshot alive here so its last owner is the mapper, not the tracker.
  if (old) retired_.push_back(std::move(old));
  collect();
}

std::shared_ptr<const MapSnapshot> MatchIndex::acquire() const {
  std::lock_guard<std::mutex> lock(swap_mutex_);
  return active_;
}

void MatchIndex::collect() {
  size_t k = 0;
  for (size_t i = 0; i < retired_.size(); ++i) {
    if (retired_[i].use_count() > 1) retired_[k++] = std::move(retired_[i]);
  }
  retired_.resize(k);
}

}  // namespace rdslam
