#include "core/spsc_ring.h"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>
#include <ctime>

namespace rdslam {

uint32_t next_pow2(uint32_t n) {
  if (n <= 1) return 1;
  if (n > 0x80000000u) return 0;
  uint32_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

namespace {
// futex(2) on the doorbell's 32-bit sequence word; process-private (no shared memory).
long futex(std::atomic<uint32_t>* word, int op, uint32_t val, const timespec* timeout) {
  static_assert(sizeof(std::atomic<uint32_t>) == sizeof(uint32_t), "futex word must be 32 bit");
  return syscall(SYS_futex, reinterpret_cast<uint32_t*>(word), op, val, timeout, nullptr, 0);
}
}  // namespace

void Doorbell::wait(uint32_t ticket, int timeout_ms) {
  if (timeout_ms <= 0) return;
  // Announce the sleeper before re-checking the word: a producer that rings after this
  // increment sees sleepers_ > 0 and wakes us; one that rang before changed seq_, and the
  // kernel refuses to sleep because the word no longer equals `ticket` (seq_cst on both).
  sleepers_.fetch_add(1, std::memory_order_seq_cst);
  if (seq_.load(std::memory_order_seq_cst) == ticket) {
    timespec ts;
    ts.tv_sec = timeout_ms / 1000;
    ts.tv_nsec = static_cast<long>(timeout_ms % 1000) * 1000000L;
    // Relative timeout; EINTR/EAGAIN/ETIMEDOUT all mean "re-check the ring".
    futex(&seq_, FUTEX_WAIT_PRIVATE, ticket, &ts);
  }
  sleepers_.fetch_sub(1, std::memory_order_seq_cst);
}

void Doorbell::ring() {
  seq_.fetch_add(1, std::memory_order_seq_cst);
  if (sleepers_.load(std::memory_order_seq_cst) != 0) {
    futex(&seq_, FUTEX_WAKE_PRIVATE, INT_MAX, nullptr);
  }
}

SlotRing::SlotRing(uint32_t min_capacity)
    : capacity_(next_pow2(min_capacity < 2 ? 2 : min_capacity)),
      mask_(capacity_ - 1),
      cells_(new std::atomic<uint32_t>[capacity_]) {
  for (uint32_t i = 0; i < capacity_; ++i) cells_[i].store(kEndOfStream);
}

bool SlotRing::try_push(uint32_t slot) {
  const uint64_t w = write_.load(std::memory_order_relaxed);
  // Acquire pairs with the CAS that advanced read_: whoever took the entry in this cell
  // has finished reading it.
  const uint64_t r = read_.load(std::memory_order_acquire);
  if (w - r >= capacity_) return false;
  cells_[w & mask_].store(slot, std::memory_order_relaxed);
  // Release: the cell, and the frame the slot index refers to, are visible to the taker.
  write_.store(w + 1, std::memory_order_release);
  return true;
}

bool SlotRing::take(uint64_t r, uint32_t& out, bool refuse_eos) {
  for (;;) {
    const uint64_t w = write_.load(std::memory_order_acquire);
    if (r == w) return false;
    const uint32_t v = cells_[r & mask_].load(std::memory_order_relaxed);
    if (refuse_eos && v == kEndOfStream) return false;
    // Exactly one taker wins entry r. On failure `r` is reloaded and the value discarded:
    // the cell may already hold a newer entry (benign, see cells_).
    if (read_.compare_exchange_weak(r, r + 1, std::memory_order_acq_rel,
                                    std::memory_order_acquire)) {
      out = v;
      return true;
    }
  }
}

bool SlotRing::evict_oldest(uint32_t& out) {
  return take(read_.load(std::memory_order_acquire), out, /*refuse_eos=*/true);
}

bool SlotRing::try_pop(uint32_t& out) {
  return take(read_.load(std::memory_order_acquire), out, /*refuse_eos=*/false);
}

}  // namespace rdslam
