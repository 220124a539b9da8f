// Commands over LCM (firmware_app/lcm_commands.h): each rdslam.command_t code changes the
// SlamLink field it names; an unknown code, SAVE_MAP without a map file and a message that is
// not a command_t are rejected and counted, and change nothing.
#include <gtest/gtest.h>
#include <lcm/lcm.h>

#include <chrono>
#include <cstring>
#include <string>
#include <vector>

#include "firmware_app/lcm_commands.h"
#include "rdslam/command_t.hpp"
#include "tests/support/lcm_test_bus.h"

namespace rdslam {
namespace {

// A bus and channel names of this process only (tests/support/lcm_test_bus.h).
const std::string kUrl = testing::private_lcm_url();
const std::string kChannelA = testing::private_channel(kChannelA);
const std::string kChannelB = testing::private_channel(kChannelB);

class Sender {
 public:
  explicit Sender(const std::string& channel) : lcm_(lcm_create(kUrl.c_str())), channel_(channel) {}
  ~Sender() { lcm_destroy(lcm_); }
  bool ok() const { return lcm_ != nullptr; }
  void send(int8_t code) {
    command_t c;
    c.utime = 1;
    c.command = code;
    std::vector<uint8_t> buf(static_cast<size_t>(c.getEncodedSize()));
    c.encode(buf.data(), 0, static_cast<int>(buf.size()));
    raw(buf.data(), buf.size());
  }
  void raw(const void* data, size_t n) {
    lcm_publish(lcm_, channel_.c_str(), data, static_cast<unsigned>(n));
  }

 private:
  lcm_t* lcm_;
  std::string channel_;
};

// Polls until `done` or 2 s.
template <class Done>
bool poll_until(LcmCommands& c, Done&& done) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (!done() && std::chrono::steady_clock::now() < end) c.poll(50);
  return done();
}

TEST(LcmCommands, EachCodeChangesItsLinkField) {
  auto link = std::make_shared<SlamLink>(2);
  // Each test its own channel (ctest may run them at the same time).
  LcmCommands cmds(kUrl, kChannelA, link, /*can_save=*/true);
  Sender s(kChannelA);
  ASSERT_TRUE(s.ok());
  s.send(command_t::LOCALIZE);
  ASSERT_TRUE(poll_until(cmds, [&] { return cmds.accepted() == 1; }));
  EXPECT_TRUE(link->localize_only.load());
  s.send(command_t::MAPPING);
  ASSERT_TRUE(poll_until(cmds, [&] { return cmds.accepted() == 2; }));
  EXPECT_FALSE(link->localize_only.load());
  s.send(command_t::SAVE_MAP);
  ASSERT_TRUE(poll_until(cmds, [&] { return cmds.accepted() == 3; }));
  EXPECT_EQ(link->save_requests.load(), 1u);
  link->localize_only.store(true);
  s.send(command_t::RESET);
  ASSERT_TRUE(poll_until(cmds, [&] { return cmds.accepted() == 4; }));
  EXPECT_EQ(link->reset_requests.load(), 1u);
  EXPECT_FALSE(link->localize_only.load()) << "a reset switches mapping on";
  EXPECT_EQ(cmds.rejected(), 0u);
  EXPECT_EQ(cmds.malformed(), 0u);
}

TEST(LcmCommands, UnknownMalformedAndUnservableCommandsAreRejectedAndCounted) {
  auto link = std::make_shared<SlamLink>(2);
  LcmCommands cmds(kUrl, kChannelB, link, /*can_save=*/false);
  Sender s(kChannelB);
  ASSERT_TRUE(s.ok());
  s.send(9);                    // unknown code
  s.send(command_t::SAVE_MAP);  // no map file configured
  const char junk[] = "not a command";
  s.raw(junk, sizeof(junk));
  command_t c;
  c.utime = 2;
  c.command = command_t::RESET;
  std::vector<uint8_t> buf(static_cast<size_t>(c.getEncodedSize()));
  c.encode(buf.data(), 0, static_cast<int>(buf.size()));
  s.raw(buf.data(), buf.size() - 1);  // truncated
  ASSERT_TRUE(poll_until(cmds, [&] { return cmds.rejected() == 2 && cmds.malformed() == 2; }))
      << cmds.rejected() << " rejected, " << cmds.malformed() << " malformed";
  EXPECT_EQ(cmds.accepted(), 0u);
  EXPECT_EQ(link->save_requests.load(), 0u);
  EXPECT_EQ(link->reset_requests.load(), 0u);
  EXPECT_FALSE(link->localize_only.load());
}

// The pure part the fuzz target (tests/fuzz/fuzz_lcm.cpp) drives: bytes in, verdict out.
TEST(LcmCommands, ApplyCommandMessageNamesTheVerdictAndTouchesOnlyTheNamedField) {
  SlamLink link(2);
  command_t c;
  c.utime = 3;
  c.command = command_t::SAVE_MAP;
  std::vector<uint8_t> buf(static_cast<size_t>(c.getEncodedSize()));
  c.encode(buf.data(), 0, static_cast<int>(buf.size()));
  int8_t code = -1;
  const auto n = static_cast<uint32_t>(buf.size());
  EXPECT_EQ(apply_command_message(buf.data(), n, link, /*can_save=*/false, &code),
            CommandVerdict::kRejected);
  EXPECT_EQ(code, int8_t{command_t::SAVE_MAP});
  EXPECT_EQ(link.save_requests.load(), 0u);
  EXPECT_EQ(apply_command_message(buf.data(), n, link, /*can_save=*/true, &code),
            CommandVerdict::kAccepted);
  EXPECT_EQ(link.save_requests.load(), 1u);
  EXPECT_EQ(apply_command_message(buf.data(), n - 1, link, true, &code),
            CommandVerdict::kMalformed);
  EXPECT_EQ(code, 0);
  buf.push_back(0);  // one byte too many: not exactly a command_t
  EXPECT_EQ(apply_command_message(buf.data(), n + 1, link, true, &code),
            CommandVerdict::kMalformed);
  EXPECT_EQ(link.save_requests.load(), 1u);
  EXPECT_EQ(link.reset_requests.load(), 0u);
  EXPECT_FALSE(link.localize_only.load());
}

TEST(LcmCommands, BadUrlThrows) {
  auto link = std::make_shared<SlamLink>(2);
  EXPECT_THROW(LcmCommands("nosuchprovider://x", "T_COMMAND", link, true), std::runtime_error);
}

}  // namespace
}  // namespace rdslam
