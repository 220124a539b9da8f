#include "core/latency_histogram.h"

namespace rdslam {

namespace {
constexpr int kSub = 8;       // linear sub-buckets per power of two
constexpr int kSubShift = 3;  // log2(kSub)
}  // namespace

int LatencyHistogram::bucket_of(int64_t us) {
  if (us < kSub) return us < 0 ? 0 : static_cast<int>(us);
  const int octave = 63 - __builtin_clzll(static_cast<unsigned long long>(us));  // >= 3
  const int sub = static_cast<int>(us >> (octave - kSubShift)) - kSub;           // 0..7
  const int index = kSub + (octave - kSubShift) * kSub + sub;
  return index < kBuckets ? index : kBuckets - 1;
}

int64_t LatencyHistogram::bucket_lo_us(int index) {
  if (index < kSub) return index;
  const int octave = kSubShift + (index - kSub) / kSub;
  const int sub = (index - kSub) % kSub;
  return static_cast<int64_t>(kSub + sub) << (octave - kSubShift);
}

int64_t LatencyHistogram::bucket_hi_us(int index) {
  if (index < kSub) return index + 1;
  const int octave = kSubShift + (index - kSub) / kSub;
  const int sub = (index - kSub) % kSub;
  return static_cast<int64_t>(kSub + sub + 1) << (octave - kSubShift);
}

void LatencyHistogram::record_us(int64_t us) {
  if (us < 0) us = 0;
  // Single writer: load+store instead of read-modify-write keeps the hot path cheap.
  auto& c = counts_[bucket_of(us)];
  c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  sum_us_.store(sum_us_.load(std::memory_order_relaxed) + us, std::memory_order_relaxed);
  if (us > max_us_.load(std::memory_order_relaxed)) max_us_.store(us, std::memory_order_relaxed);
  // Release: a reader that sees the new total also sees the bucket it belongs to.
  total_.store(total_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

LatencyHistogram::Snapshot LatencyHistogram::snapshot() const {
  Snapshot s;
  s.total = total_.load(std::memory_order_acquire);
  uint64_t sum = 0;
  for (int i = 0; i < kBuckets; ++i) {
    s.counts[i] = counts_[i].load(std::memory_order_relaxed);
    sum += s.counts[i];
  }
  // Buckets may be ahead of total_ when the writer ran meanwhile: use what was counted.
  s.total = sum;
  s.sum_us = sum_us_.load(std::memory_order_relaxed);
  s.max_us = max_us_.load(std::memory_order_relaxed);
  return s;
}

double LatencyHistogram::Snapshot::percentile_ms(double q) const {
  if (total == 0) return 0.0;
  if (q < 0) q = 0;
  if (q > 1) q = 1;
  // Rank of the sample (1-based) at quantile q: the smallest rank covering q of the data.
  uint64_t rank = static_cast<uint64_t>(q * static_cast<double>(total) + 0.999999);
  if (rank < 1) rank = 1;
  uint64_t seen = 0;
  for (int i = 0; i < kBuckets; ++i) {
    seen += counts[i];
    if (seen >= rank) {
      const double mid_us = 0.5 * static_cast<double>(bucket_lo_us(i) + bucket_hi_us(i) - 1);
      return mid_us / 1000.0;
    }
  }
  return static_cast<double>(bucket_lo_us(kBuckets - 1)) / 1000.0;
}

LatencyHistogram::Snapshot LatencyHistogram::Snapshot::since(const Snapshot& earlier) const {
  Snapshot d;
  for (int i = 0; i < kBuckets; ++i) {
    d.counts[i] = counts[i] >= earlier.counts[i] ? counts[i] - earlier.counts[i] : 0;
    d.total += d.counts[i];
  }
  d.sum_us = sum_us - earlier.sum_us;
  d.max_us = max_us;
  return d;
}

}  // namespace rdslam
