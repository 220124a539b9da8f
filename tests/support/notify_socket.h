// Test helper: a NOTIFY_SOCKET owned by the test, i.e. what systemd listens on for a
// Type=notify service (an AF_UNIX datagram socket bound to a filesystem path). Tests point
// the code under test at path() and read every datagram with a timestamp.
//
// Ownership: owns the socket and its temporary directory. Threads: one test thread.
#pragma once

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace rdslam::testing {

struct NotifyMessage {
  double t_s = 0.0;  // seconds since the socket was created
  std::string text;  // raw datagram, e.g. "READY=1\nSTATUS=tracking"
  bool has(const std::string& assignment) const {
    // Assignments are newline-separated; match whole lines ("WATCHDOG=1", "STATUS=...").
    size_t pos = 0;
    while (pos <= text.size()) {
      const size_t end = text.find('\n', pos);
      const std::string line = text.substr(pos, end == std::string::npos ? end : end - pos);
      if (line == assignment) return true;
      if (end == std::string::npos) break;
      pos = end + 1;
    }
    return false;
  }
  // Value of KEY= in this message, or "" when absent.
  std::string value(const std::string& key) const {
    const std::string k = key + "=";
    size_t pos = 0;
    while (pos < text.size()) {
      const size_t end = text.find('\n', pos);
      const std::string line = text.substr(pos, end == std::string::npos ? end : end - pos);
      if (line.rfind(k, 0) == 0) return line.substr(k.size());
      if (end == std::string::npos) break;
      pos = end + 1;
    }
    return "";
  }
};

class NotifySocket {
 public:
  NotifySocket() : start_(std::chrono::steady_clock::now()) {
    char tmpl[] = "/tmp/rdslam-notify-XXXXXX";
    if (!mkdtemp(tmpl)) throw std::runtime_error("mkdtemp failed");
    dir_ = tmpl;
    path_ = dir_ + "/notify.sock";
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket(AF_UNIX, SOCK_DGRAM) failed");
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path_.c_str(), sizeof(addr.sun_path) - 1);
    if (bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) {
      throw std::runtime_error("bind(" + path_ + ") failed: " + std::strerror(errno));
    }
  }
  ~NotifySocket() {
    if (fd_ >= 0) close(fd_);
    unlink(path_.c_str());
    rmdir(dir_.c_str());
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  const std::string& path() const { return path_; }

  // Next datagram within `timeout_ms`; false on timeout.
  bool receive(NotifyMessage& out, int timeout_ms) {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) return false;
    char buf[4096];
    const ssize_t n = recv(fd_, buf, sizeof(buf), 0);
    if (n < 0) return false;
    out.text.assign(buf, static_cast<size_t>(n));
    out.t_s = elapsed_s();
    return true;
  }
  // Every datagram that arrives within `duration_ms`.
  std::vector<NotifyMessage> collect(int duration_ms) {
    std::vector<NotifyMessage> out;
    const double until = elapsed_s() + duration_ms * 1e-3;
    for (double now = elapsed_s(); now < until; now = elapsed_s()) {
      NotifyMessage m;
      if (receive(m, static_cast<int>((until - now) * 1e3) + 1)) out.push_back(m);
    }
    return out;
  }
  double elapsed_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
  std::string dir_, path_;
  int fd_ = -1;
};

}  // namespace rdslam::testing
