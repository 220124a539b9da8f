#include "drivers/v4l2_syscalls.h"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "core/frame_source.h"

namespace rdslam {
namespace {

class SystemV4l2 final : public V4l2Syscalls {
 public:
  int open(const char* path, int flags) override { return ::open(path, flags); }
  int close(int fd) override { return ::close(fd); }
  int ioctl(int fd, unsigned long request, void* arg) override { return ::ioctl(fd, request, arg); }
  void* mmap(size_t length, int fd, off_t offset) override {
    return ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset);
  }
  int munmap(void* addr, size_t length) override { return ::munmap(addr, length); }
  int poll(int fd, short events, short* revents, int timeout_ms) override {
    struct pollfd p {};
    p.fd = fd;
    p.events = events;
    const int r = ::poll(&p, 1, timeout_ms);
    if (revents) *revents = p.revents;
    return r;
  }
  int64_t monotonic_ns() override { return mono_now_ns(); }
  void sleep_ns(int64_t ns) override {
    if (ns <= 0) return;
    struct timespec ts {};
    ts.tv_sec = static_cast<time_t>(ns / 1000000000LL);
    ts.tv_nsec = static_cast<long>(ns % 1000000000LL);
    while (clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, &ts) == EINTR) {
    }
  }
  std::vector<std::string> list_video_devices() override {
    std::vector<std::pair<long, std::string>> found;
    DIR* d = opendir("/dev");
    if (!d) return {};
    while (const dirent* e = readdir(d)) {
      if (std::strncmp(e->d_name, "video", 5) != 0) continue;
      char* end = nullptr;
      const long n = std::strtol(e->d_name + 5, &end, 10);
      if (end == e->d_name + 5 || *end != '\0') continue;
      found.emplace_back(n, std::string("/dev/") + e->d_name);
    }
    closedir(d);
    std::sort(found.begin(), found.end());
    std::vector<std::string> out;
    for (auto& f : found) out.push_back(std::move(f.second));
    return out;
  }
};

}  // namespace

V4l2Syscalls& system_v4l2() {
  static SystemV4l2 sys;
  return sys;
}

int xioctl(V4l2Syscalls& sys, int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = sys.ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

}  // namespace rdslam
