#include "core/match_index.h"

namespace rdslam {

void MatchIndex::publish(std::shared_ptr<const MapSnapshot> snap) {
  const int active = active_.load(std::memory_order_seq_cst);
  const int reading = reading_.load(std::memory_order_seq_cst);
  int j = 0;
  while (j == active || j == reading) ++j;  // kSlots = 3: one of them is free
  // Keep the slot's old snapshot alive here so its last owner is the mapper, not the tracker.
  if (slots_[j]) retired_.push_back(std::move(slots_[j]));  // normally emptied by collect()
  slots_[j] = std::move(snap);
  active_.store(j, std::memory_order_seq_cst);
  version_.fetch_add(1, std::memory_order_release);
  collect();
}

std::shared_ptr<const MapSnapshot> MatchIndex::acquire() const {
  for (;;) {
    const int i = active_.load(std::memory_order_seq_cst);
    if (i < 0) return nullptr;
    reading_.store(i, std::memory_order_seq_cst);
    // Still active after the announcement: publish() cannot be writing slot i now, and will
    // not write it until reading_ is cleared (it picks a slot that is neither).
    if (active_.load(std::memory_order_seq_cst) == i) {
      std::shared_ptr<const MapSnapshot> s = slots_[i];
      reading_.store(-1, std::memory_order_release);
      return s;
    }
  }
}

void MatchIndex::collect() {
  // Slots that are neither active nor announced cannot be read again (acquire() re-checks
  // the active index): their snapshots join the retired ones.
  const int active = active_.load(std::memory_order_seq_cst);
  const int reading = reading_.load(std::memory_order_seq_cst);
  for (int j = 0; j < kSlots; ++j) {
    if (j != active && j != reading && slots_[j]) retired_.push_back(std::move(slots_[j]));
  }
  size_t k = 0;
  for (size_t i = 0; i < retired_.size(); ++i) {
    if (retired_[i].use_count() > 1) retired_[k++] = std::move(retired_[i]);
  }
  retired_.resize(k);
}

}  // namespace rdslam
