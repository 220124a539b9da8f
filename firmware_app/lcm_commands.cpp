#include "firmware_app/lcm_commands.h"

#include <lcm/lcm.h>

#include <cstdint>
#include <stdexcept>

#include "core/log.h"
#include "rdslam/command_t.hpp"

namespace rdslam {

LcmCommands::LcmCommands(const std::string& url, const std::string& channel,
                         std::shared_ptr<SlamLink> link, bool can_save)
    : link_(std::move(link)), can_save_(can_save) {
  lcm_ = lcm_create(url.c_str());
  if (!lcm_) throw std::runtime_error("lcm: cannot open provider URL '" + url + "'");
  sub_ = lcm_subscribe(lcm_, channel.c_str(), &LcmCommands::on_message, this);
  if (!sub_) {
    lcm_destroy(lcm_);
    throw std::runtime_error("lcm: cannot subscribe to " + channel);
  }
}

LcmCommands::~LcmCommands() {
  if (sub_) lcm_unsubscribe(lcm_, sub_);
  lcm_destroy(lcm_);
}

void LcmCommands::poll(int timeout_ms) {
  // lcm_handle_timeout returns > 0 after handling a message, 0 on timeout, < 0 on error.
  while (lcm_handle_timeout(lcm_, timeout_ms) > 0) timeout_ms = 0;
}

void LcmCommands::on_message(const lcm_recv_buf_t* rbuf, const char* /*channel*/, void* self) {
  static_cast<LcmCommands*>(self)->handle(rbuf->data, rbuf->data_size);
}

CommandVerdict apply_command_message(const void* data, uint32_t size, SlamLink& link, bool can_save,
                                     int8_t* code) {
  *code = 0;
  command_t c;
  if (size > static_cast<uint32_t>(INT32_MAX) || c.decode(data, 0, static_cast<int>(size)) < 0 ||
      c.getEncodedSize() != static_cast<int>(size)) {
    return CommandVerdict::kMalformed;
  }
  *code = c.command;
  switch (c.command) {
    case command_t::RESET:
      link.localize_only.store(false);
      link.reset_requests.fetch_add(1);
      return CommandVerdict::kAccepted;
    case command_t::SAVE_MAP:
      if (!can_save) return CommandVerdict::kRejected;
      link.save_requests.fetch_add(1);
      return CommandVerdict::kAccepted;
    case command_t::LOCALIZE:
      link.localize_only.store(true);
      return CommandVerdict::kAccepted;
    case command_t::MAPPING:
      link.localize_only.store(false);
      return CommandVerdict::kAccepted;
    default:
      return CommandVerdict::kRejected;
  }
}

void LcmCommands::handle(const void* data, uint32_t size) {
  int8_t code = 0;
  switch (apply_command_message(data, size, *link_, can_save_, &code)) {
    case CommandVerdict::kMalformed:
      if (malformed_.fetch_add(1) < 5) {
        RDSLAM_LOG_WARN("command: malformed message (%u bytes, not rdslam.command_t): rejected",
                        size);
      }
      return;
    case CommandVerdict::kRejected:
      if (rejected_.fetch_add(1) < 5) {
        if (code == command_t::SAVE_MAP) {
          RDSLAM_LOG_WARN("command: save_map rejected: no map file configured (map.save_path)");
        } else {
          RDSLAM_LOG_WARN("command: unknown command code %d: rejected", int(code));
        }
      }
      return;
    case CommandVerdict::kAccepted:
      break;
  }
  accepted_.fetch_add(1);
  static const char* const kNames[] = {"", "reset", "save_map", "localize", "mapping"};
  RDSLAM_LOG_INFO("command: %s", kNames[code]);
}

}  // namespace rdslam
