// Exact conversion between decimal-seconds text ("1403715273.262142976") and integer
// nanoseconds. A double holds only ~16 significant digits, so a Unix time in seconds with 9
// decimals does not survive a round trip through double; dataset readers and writers
// (TUM rgb.txt, groundtruth.txt, record/replay) use these instead so that timestamps are
// bit-identical after write -> read.
//
// Ownership: free functions, no state. Threads: any.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace rdslam {

// Parses "[-]S[.F]" (S, F decimal digits, at least one digit overall; F may have any length,
// digits beyond the 9th are rounded half away from zero). Returns false on anything else,
// including overflow of int64 ns. No allocation, locale-independent.
bool parse_seconds_ns(std::string_view text, int64_t& out_ns);

// Formats ns as seconds with exactly 9 decimals ("1403715273.262142976"); the inverse of
// parse_seconds_ns for every int64 value.
std::string format_seconds_ns(int64_t ns);

}  // namespace rdslam
