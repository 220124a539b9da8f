// A private LCM bus for one test process: a ttl=0 multicast URL (the traffic never leaves the
// host) on a port drawn for this process, and a channel suffix drawn for this process.
//
// Why both: multicast with ttl=0 is shared by every process on the host, including other test
// processes of this run (ctest -j) and test runs of other checkouts or CI jobs that share the
// host's network, possibly in other PID namespaces. A fixed port and a fixed channel name let
// one test count another's messages (a CI failure seen once: 4 images received where 2 were
// sent). The port spreads processes over 20000 ports; the suffix, from the PID and a random
// number drawn once per process, makes a collision of both vanishingly unlikely.
//
// Header-only; any thread may call (the values are computed once, thread-safely).
#pragma once

#include <unistd.h>

#include <random>
#include <string>

namespace rdslam::testing {

// A number drawn once per process: PID mixed with std::random_device.
inline unsigned process_nonce() {
  static const unsigned nonce = [] {
    std::random_device rd;
    return static_cast<unsigned>(::getpid()) * 2654435761u ^ rd();
  }();
  return nonce;
}

// udpm://239.255.76.67:<port>?ttl=0, port in [20000, 40000); `salt` separates buses inside
// one process.
inline std::string private_lcm_url(int salt = 0) {
  const unsigned port = 20000u + (process_nonce() + 7u * static_cast<unsigned>(salt)) % 20000u;
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

// `base` + "_" + the process nonce in hex: a channel name no other process uses.
inline std::string private_channel(const std::string& base) {
  static const char* kHex = "0123456789ABCDEF";
  std::string s = base + "_";
  for (int shift = 28; shift >= 0; shift -= 4) s += kHex[(process_nonce() >> shift) & 0xF];
  return s;
}

}  // namespace rdslam::testing
