// Fixed-bucket latency histogram: no allocation, lock-free, one writer and any readers.
//
// Buckets are log-linear (HdrHistogram style): exact microseconds below 8 us, then 8
// linear sub-buckets per power of two, so every bucket is at most 12.5% wide and the
// reported percentile (bucket midpoint) is within about 6% of the true value, from 1 us to
// about 67 s (larger values land in the last bucket). 192 buckets = 1.5 KiB of counters.
//
// Per-interval percentiles (the 1 Hz status): take a Snapshot each interval and subtract the
// previous one (Snapshot::since()).
//
// Ownership: value type embedded in its owner. Threads: record_*() from ONE thread (the
// stage being timed); snapshot() from any thread (relaxed atomics: a snapshot taken while
// the writer runs may miss the latest sample, never tears a counter).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace rdslam {

class LatencyHistogram {
 public:
  static constexpr int kBuckets = 192;

  struct Snapshot {
    std::array<uint64_t, kBuckets> counts{};
    uint64_t total = 0;
    int64_t sum_us = 0;
    int64_t max_us = 0;  // since start (not per interval)

    // Value below which a fraction `q` in [0, 1] of the samples fall, in milliseconds
    // (bucket midpoint); 0 when empty.
    double percentile_ms(double q) const;
    double mean_ms() const { return total ? static_cast<double>(sum_us) / total / 1000.0 : 0.0; }
    // Samples recorded after `earlier` (same histogram, earlier snapshot).
    Snapshot since(const Snapshot& earlier) const;
  };

  void record_ns(int64_t ns) { record_us(ns / 1000); }
  void record_us(int64_t us);
  Snapshot snapshot() const;

  // Bucket layout, exposed for tests: index of a value and the [lo, hi) range of a bucket.
  static int bucket_of(int64_t us);
  static int64_t bucket_lo_us(int index);
  static int64_t bucket_hi_us(int index);

 private:
  std::array<std::atomic<uint64_t>, kBuckets> counts_{};
  std::atomic<uint64_t> total_{0};
  std::atomic<int64_t> sum_us_{0};
  std::atomic<int64_t> max_us_{0};
};

}  // namespace rdslam
