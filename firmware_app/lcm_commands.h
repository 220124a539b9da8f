// Commands over LCM (issue 24 item 4): `rdslam run` subscribes to rdslam.command_t on
// lcm.command_channel (default RDSLAM_COMMAND) and applies each command to the SLAM system
// through the SlamLink's command fields (core/keyframe.h):
//   RESET     start a new map epoch, mapping on (SlamLink::reset_requests; the tracker serves
//             it at its next frame as after a long loss, a no-op while it is INITIALIZING)
//   SAVE_MAP  save the map to map.save_path (SlamLink::save_requests, served by the mapper)
//   LOCALIZE  localization only, the map is frozen (SlamLink::localize_only)
//   MAPPING   the map grows and is updated again
// A message that does not decode as rdslam.command_t (another type, truncated) is malformed;
// a code not listed, or SAVE_MAP without a map file, is rejected. Both are counted and logged
// (the first few), never fatal.
//
// Security: LCM has no authentication or encryption. Anyone who can send to lcm.url can reset
// or freeze the map. The default URL's ttl=0 keeps multicast on this host; do not raise it on
// an untrusted network, or set lcm.command_channel to "" to ignore commands.
//
// Ownership: owns its own lcm_t (the publisher's is written by the publisher thread).
// Threads: construct and poll() on the supervising thread (no thread of its own); the counters
// from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "core/keyframe.h"

typedef struct _lcm_t lcm_t;
typedef struct _lcm_subscription_t lcm_subscription_t;
typedef struct _lcm_recv_buf_t lcm_recv_buf_t;

namespace rdslam {

// What one received message did (apply_command_message).
enum class CommandVerdict { kAccepted, kRejected, kMalformed };

// Decodes one message as rdslam.command_t and applies it to `link` (the table above). Pure
// apart from `link`'s atomics: no LCM, no logging, no allocation beyond the decoder's, so
// that the fuzz target (tests/fuzz/fuzz_lcm.cpp) runs it on any bytes. `code` receives the
// decoded command code (0 when malformed). Any thread.
CommandVerdict apply_command_message(const void* data, uint32_t size, SlamLink& link, bool can_save,
                                     int8_t* code);

class LcmCommands {
 public:
  // Throws std::runtime_error when the URL cannot be opened. `can_save`: a map file is
  // configured (SAVE_MAP is rejected otherwise).
  LcmCommands(const std::string& url, const std::string& channel, std::shared_ptr<SlamLink> link,
              bool can_save);
  ~LcmCommands();
  LcmCommands(const LcmCommands&) = delete;
  LcmCommands& operator=(const LcmCommands&) = delete;

  // Handles the messages waiting now; waits at most `timeout_ms` for the first one.
  void poll(int timeout_ms = 0);

  uint64_t accepted() const { return accepted_.load(std::memory_order_relaxed); }
  uint64_t rejected() const { return rejected_.load(std::memory_order_relaxed); }
  uint64_t malformed() const { return malformed_.load(std::memory_order_relaxed); }

 private:
  static void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* self);
  void handle(const void* data, uint32_t size);

  lcm_t* lcm_ = nullptr;
  lcm_subscription_t* sub_ = nullptr;
  std::shared_ptr<SlamLink> link_;
  bool can_save_;
  std::atomic<uint64_t> accepted_{0}, rejected_{0}, malformed_{0};
};

}  // namespace rdslam
