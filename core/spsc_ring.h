// Lock-free rings that connect rdslam's pipeline threads (capture -> tracker -> publisher,
// tracker -> mapper), and the doorbell a consumer blocks on while a ring is empty.
//
// - SpscRing<T>: single-producer single-consumer FIFO of preallocated T (after
//   rigtorp/SPSCQueue): power-of-two capacity fixed at construction, the producer's and the
//   consumer's index on separate cache lines, each side keeps a cached copy of the other
//   side's index so the common case touches no shared cache line. Elements are constructed
//   once at start-up; push copies into a slot (or the producer fills it in place with
//   back()/commit()), the consumer reads it in place with front()/pop(). Never allocates
//   after construction, never throws after construction, returns bool when full/empty.
// - SlotRing: a ring of pool-slot indices (uint32_t) with the "newest frame wins" operation
//   the capture thread needs (ArduPilot's push_force, made safe for two threads):
//     evict_oldest(out) is equivalent to: the producer pops the oldest entry itself.
//   Producer and consumer both advance the read index with a compare-and-swap, so every
//   entry is taken by exactly one of them: drops are counted exactly where they happen.
// - Doorbell: an eventcount on a futex. The consumer takes a ticket, re-checks its ring,
//   and sleeps only if nothing changed since the ticket; the producer's ring() is one atomic
//   increment plus a futex wake only when someone sleeps. No lost wake-ups, no sleep-polling.
//
// Ownership: each ring owns its storage (allocated in the constructor). Threads: for each
// ring exactly one producer thread and one consumer thread; the methods below say which.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

namespace rdslam {

// 64 bytes on x86-64 and on the Cortex-A cores rdslam targets. Fixed rather than
// std::hardware_destructive_interference_size, which GCC warns is ABI-unstable.
constexpr size_t kCacheLineBytes = 64;

// Smallest power of two >= n (n >= 1); 0 when it would not fit in 32 bits.
uint32_t next_pow2(uint32_t n);

class Doorbell {
 public:
  // Consumer: take a ticket BEFORE checking the ring for data.
  uint32_t ticket() const { return seq_.load(std::memory_order_seq_cst); }
  // Consumer: sleep until ring() was called after `ticket` was taken, or `timeout_ms`
  // passes. Returns immediately when ring() already happened. Spurious returns are allowed
  // (callers re-check their ring), which is why no result is returned.
  void wait(uint32_t ticket, int timeout_ms);
  // Producer: after publishing data into the ring.
  void ring();

 private:
  std::atomic<uint32_t> seq_{0};
  std::atomic<uint32_t> sleepers_{0};
};

template <typename T>
class SpscRing {
 public:
  // Capacity is rounded up to a power of two (>= 2). Allocates all slots (start-up only).
  explicit SpscRing(uint32_t min_capacity)
      : capacity_(next_pow2(min_capacity < 2 ? 2 : min_capacity)),
        mask_(capacity_ - 1),
        slots_(new T[capacity_]) {}
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  uint32_t capacity() const { return capacity_; }

  // Producer: copy `v` into the ring; false (nothing written) when full.
  bool try_push(const T& v) {
    T* slot = back();
    if (!slot) return false;
    *slot = v;
    commit();
    return true;
  }
  // Producer: the next free slot to fill in place, or nullptr when full. The slot still
  // holds an old element: overwrite every field you rely on, then commit().
  T* back() {
    const uint64_t w = write_.load(std::memory_order_relaxed);
    if (w - read_cache_ >= capacity_) {
      // Acquire: the consumer's reads of that slot happened before it advanced read_.
      read_cache_ = read_.load(std::memory_order_acquire);
      if (w - read_cache_ >= capacity_) return nullptr;
    }
    return &slots_[w & mask_];
  }
  // Producer: publish the slot returned by back().
  void commit() {
    // Release: the slot's contents are visible to a consumer that acquires write_.
    write_.store(write_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

  // Consumer: the oldest element (valid until pop()), or nullptr when empty.
  T* front() {
    const uint64_t r = read_.load(std::memory_order_relaxed);
    if (r == write_cache_) {
      write_cache_ = write_.load(std::memory_order_acquire);
      if (r == write_cache_) return nullptr;
    }
    return &slots_[r & mask_];
  }
  // Consumer: release the element returned by front().
  void pop() { read_.store(read_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  // Consumer: copy out and pop; false when empty.
  bool try_pop(T& out) {
    T* f = front();
    if (!f) return false;
    out = *f;
    pop();
    return true;
  }

  // Either thread; exact only when the other side is idle (tests, statistics).
  uint32_t size_approx() const {
    return static_cast<uint32_t>(write_.load(std::memory_order_acquire) -
                                 read_.load(std::memory_order_acquire));
  }

 private:
  const uint32_t capacity_;
  const uint32_t mask_;
  std::unique_ptr<T[]> slots_;
  // Monotonic 64-bit counters (never wrap in practice); slot = counter & mask_.
  alignas(kCacheLineBytes) std::atomic<uint64_t> write_{0};  // written by the producer
  uint64_t read_cache_ = 0;                                  // producer's copy of read_
  alignas(kCacheLineBytes) std::atomic<uint64_t> read_{0};   // written by the consumer
  uint64_t write_cache_ = 0;                                 // consumer's copy of write_
  char pad_[kCacheLineBytes - sizeof(uint64_t)];             // keep neighbours off our line
};

class SlotRing {
 public:
  // A value no pool slot ever has; pipelines use it as the end-of-stream message.
  static constexpr uint32_t kEndOfStream = 0xFFFFFFFFu;

  // Capacity rounded up to a power of two. Allocates (start-up only).
  explicit SlotRing(uint32_t min_capacity);
  SlotRing(const SlotRing&) = delete;
  SlotRing& operator=(const SlotRing&) = delete;

  uint32_t capacity() const { return capacity_; }

  // Producer: append `slot`; false when full (size the ring so this cannot happen).
  bool try_push(uint32_t slot);
  // Producer: remove the oldest entry and hand it back to the producer ("newest frame
  // wins": the capture thread recycles a frame the tracker never saw). Equivalent to a
  // pop() done by the producer. False when the ring is empty or when the oldest entry is
  // kEndOfStream (an end-of-stream message is never dropped).
  bool evict_oldest(uint32_t& out);
  // Consumer: take the oldest entry; false when empty.
  bool try_pop(uint32_t& out);

  // Either thread; exact only when both sides are idle.
  uint32_t size_approx() const {
    return static_cast<uint32_t>(write_.load(std::memory_order_acquire) -
                                 read_.load(std::memory_order_acquire));
  }

 private:
  // Takes entry `r` (the read index the caller saw) if nobody took it first.
  bool take(uint64_t r, uint32_t& out, bool refuse_eos);

  const uint32_t capacity_;
  const uint32_t mask_;
  // Atomic cells: a consumer may read a cell while the producer, having evicted that very
  // entry, refills it; the reader's CAS on read_ then fails and the torn-free value is
  // discarded. Relaxed atomics make that benign race well-defined (and TSan-clean).
  std::unique_ptr<std::atomic<uint32_t>[]> cells_;
  alignas(kCacheLineBytes) std::atomic<uint64_t> write_{0};  // producer only
  alignas(kCacheLineBytes) std::atomic<uint64_t> read_{0};   // CAS by both sides
  char pad_[kCacheLineBytes - sizeof(uint64_t)];
};

}  // namespace rdslam
