#include "core/log.h"

#include <atomic>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace rdslam {
namespace {
std::atomic<int> g_level{static_cast<int>(LogLevel::kInfo)};
const bool g_journal = std::getenv("JOURNAL_STREAM") != nullptr;
}  // namespace

void set_log_level(LogLevel level) {
  g_level.store(static_cast<int>(level));
}
LogLevel log_level() {
  return static_cast<LogLevel>(g_level.load());
}

bool parse_log_level(const char* text, LogLevel& out) {
  static const char* const kNames[] = {"debug", "info", "warn", "error"};
  for (int i = 0; i < 4; ++i) {
    if (std::strcmp(text, kNames[i]) == 0) {
      out = static_cast<LogLevel>(i);
      return true;
    }
  }
  return false;
}

void log_write(LogLevel level, const char* fmt, ...) {
  if (static_cast<int>(level) < g_level.load(std::memory_order_relaxed)) return;
  static const char* const kTag[] = {"debug", "info", "warn", "error"};
  static const int kSyslog[] = {7, 6, 4, 3};
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(msg, sizeof(msg), fmt, ap);
  va_end(ap);
  const int i = static_cast<int>(level);
  if (g_journal) {
    std::fprintf(stderr, "<%d>%s\n", kSyslog[i], msg);
  } else {
    std::fprintf(stderr, "[%s] %s\n", kTag[i], msg);
  }
}

}  // namespace rdslam
