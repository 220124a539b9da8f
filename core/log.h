// Minimal stderr logging, journald-friendly: when stderr is connected to the journal
// (JOURNAL_STREAM set by systemd) each line carries a syslog priority prefix "<N>", so
// `journalctl -p warning -u rdslam` filters correctly; otherwise lines read "[level] msg".
//
// Threads: any thread; each call writes one line with a single fprintf (atomic per line for
// lines below PIPE_BUF). Formatting uses a stack buffer: no heap allocation.
#pragma once

namespace rdslam {

enum class LogLevel : int { kDebug = 0, kInfo = 1, kWarn = 2, kError = 3 };

void set_log_level(LogLevel level);
LogLevel log_level();
// Parses "debug" | "info" | "warn" | "error"; returns false on anything else.
bool parse_log_level(const char* text, LogLevel& out);
void log_write(LogLevel level, const char* fmt, ...) __attribute__((format(printf, 2, 3)));

}  // namespace rdslam

#define RDSLAM_LOG_DEBUG(...) ::rdslam::log_write(::rdslam::LogLevel::kDebug, __VA_ARGS__)
#define RDSLAM_LOG_INFO(...) ::rdslam::log_write(::rdslam::LogLevel::kInfo, __VA_ARGS__)
#define RDSLAM_LOG_WARN(...) ::rdslam::log_write(::rdslam::LogLevel::kWarn, __VA_ARGS__)
#define RDSLAM_LOG_ERROR(...) ::rdslam::log_write(::rdslam::LogLevel::kError, __VA_ARGS__)
