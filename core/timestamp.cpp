#include "core/timestamp.h"

#include <cinttypes>
#include <cstdio>
#include <limits>

namespace rdslam {

bool parse_seconds_ns(std::string_view text, int64_t& out_ns) {
  size_t i = 0;
  bool negative = false;
  if (i < text.size() && (text[i] == '-' || text[i] == '+')) {
    negative = text[i] == '-';
    ++i;
  }
  // Accumulate as a non-negative magnitude in unsigned arithmetic; check overflow against
  // |INT64_MIN| so "-9223372036.854775808" parses.
  const uint64_t limit = static_cast<uint64_t>(std::numeric_limits<int64_t>::max()) + 1u;
  uint64_t sec = 0;
  int digits = 0;
  for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i, ++digits) {
    sec = sec * 10u + static_cast<uint64_t>(text[i] - '0');
    if (sec > limit / 1000000000u) return false;
  }
  uint64_t frac = 0;
  int frac_digits = 0;
  bool round_up = false;
  if (i < text.size() && text[i] == '.') {
    ++i;
    for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i, ++digits, ++frac_digits) {
      if (frac_digits < 9) {
        frac = frac * 10u + static_cast<uint64_t>(text[i] - '0');
      } else if (frac_digits == 9) {
        round_up = text[i] >= '5';
      }
    }
  }
  if (digits == 0 || i != text.size()) return false;
  for (int k = frac_digits; k < 9; ++k) frac *= 10u;
  uint64_t mag = sec * 1000000000u + frac + (round_up ? 1u : 0u);
  if (mag > limit || (!negative && mag == limit)) return false;
  out_ns = negative ? static_cast<int64_t>(0u - mag) : static_cast<int64_t>(mag);
  return true;
}

std::string format_seconds_ns(int64_t ns) {
  // Work on the unsigned magnitude so INT64_MIN formats correctly.
  const bool negative = ns < 0;
  const uint64_t mag = negative ? 0u - static_cast<uint64_t>(ns) : static_cast<uint64_t>(ns);
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "",
                mag / 1000000000u, mag % 1000000000u);
  return buf;
}

}  // namespace rdslam
