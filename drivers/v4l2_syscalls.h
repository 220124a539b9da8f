// A thin seam over the system calls the V4L2 source makes (open, ioctl, mmap, poll, close,
// the monotonic clock and sleeping), so the streaming state machine in v4l2_source.cpp can
// be unit-tested against a fake device that simulates unplug, EIO and corrupt frames, with
// a simulated clock (tests/unit/test_v4l2_source.cpp). Production code uses system_v4l2().
//
// Every call has POSIX semantics: failures return -1 (mmap: MAP_FAILED) and set errno.
//
// Ownership: system_v4l2() is a process-wide stateless object. Threads: any thread; the
// real implementation only forwards to the kernel.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rdslam {

class V4l2Syscalls {
 public:
  virtual ~V4l2Syscalls() = default;
  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  // mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset).
  virtual void* mmap(size_t length, int fd, off_t offset) = 0;
  virtual int munmap(void* addr, size_t length) = 0;
  // poll() on one descriptor; `revents` receives the returned events.
  virtual int poll(int fd, short events, short* revents, int timeout_ms) = 0;
  // CLOCK_MONOTONIC in ns: the clock V4L2 buffer timestamps use.
  virtual int64_t monotonic_ns() = 0;
  virtual void sleep_ns(int64_t ns) = 0;
  // Video device nodes (/dev/videoN), sorted by N. Start-up only (allocates).
  virtual std::vector<std::string> list_video_devices() = 0;
};

// The real kernel interface.
V4l2Syscalls& system_v4l2();

// ioctl that retries on EINTR (a signal during a blocking ioctl is not a failure).
int xioctl(V4l2Syscalls& sys, int fd, unsigned long request, void* arg);

}  // namespace rdslam
