// A simulated UVC camera behind the V4l2Syscalls seam, for tests/unit/test_v4l2_source.cpp
// and test_v4l2_sources_list.cpp. It implements the ioctls the source uses with the kernel's
// buffer-queue semantics (queued -> filled at the frame period -> dequeued -> requeued, a
// frame is dropped when no buffer is queued), a simulated CLOCK_MONOTONIC that poll() and
// sleep_ns() advance, and fault injection: unplug/replug, EIO, truncated MJPEG payloads,
// V4L2_BUF_FLAG_ERROR.
#pragma once

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "drivers/v4l2_syscalls.h"

namespace rdslam::testing {

class FakeV4l2 : public V4l2Syscalls {
 public:
  // ---- configuration (set before opening) ----
  std::vector<uint32_t> formats{V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  int width = 640;
  int height = 480;
  int64_t period_ns = 33333333;  // 30 fps
  // Payloads per format, cycled through; frame k uses payload k % size.
  std::map<uint32_t, std::vector<std::vector<uint8_t>>> payloads;
  // Fault injection, by the frame's kernel sequence number.
  std::set<uint32_t> truncate_frames;    // payload cut to 40 %
  std::set<uint32_t> error_flag_frames;  // V4L2_BUF_FLAG_ERROR
  std::set<uint32_t> eio_frames;         // DQBUF fails with EIO instead of delivering it
  int64_t unplug_at_ns = -1;             // device disappears at this time ...
  int64_t replug_at_ns = -1;             // ... and comes back (as a new open) at this time
  bool paused = false;                   // no frames are produced

  // ---- observations ----
  int opens = 0;
  int open_fds = 0;
  int mapped = 0;
  int64_t now_ns = 1000LL * 1000000000LL;
  std::map<uint32_t, int32_t> controls_set;
  uint32_t active_format = 0;
  v4l2_fract timeperframe{1, 30};

  // ---- V4l2Syscalls ----
  int open(const char* path, int) override {
    if (std::string(path) == "/dev/video1") return open_meta();
    if (std::string(path) != "/dev/video0" || !present()) {
      errno = ENOENT;
      return -1;
    }
    ++opens;
    ++open_fds;
    fd_ = 100 + opens;  // a new descriptor per open: stale ones fail after an unplug
    fd_opened_ns_ = now_ns;
    streaming_ = false;
    return fd_;
  }
  int close(int fd) override {
    if (fd == meta_fd_) {
      meta_fd_ = -1;
      --open_fds;
      return 0;
    }
    if (fd != fd_ && fd < 100) {
      errno = EBADF;
      return -1;
    }
    --open_fds;
    if (fd == fd_) {
      streaming_ = false;
      queued_.clear();
      done_.clear();
    }
    return 0;
  }
  void* mmap(size_t length, int fd, off_t offset) override {
    const size_t i = static_cast<size_t>(offset) / kOffsetStep;
    if (fd != fd_ || i >= storage_.size() || length != storage_[i].size()) {
      errno = EINVAL;
      return MAP_FAILED;
    }
    ++mapped;
    return storage_[i].data();
  }
  int munmap(void*, size_t) override {
    --mapped;
    return 0;
  }
  int poll(int fd, short, short* revents, int timeout_ms) override {
    *revents = 0;
    if (!fd_alive(fd)) {
      *revents = POLLERR;
      return 1;
    }
    produce();
    if (done_.empty() && timeout_ms > 0) {
      const int64_t until = now_ns + static_cast<int64_t>(timeout_ms) * 1000000LL;
      int64_t t = (paused || !streaming_) ? until : std::min(until, next_frame_ns_);
      if (unplug_at_ns >= 0 && now_ns < unplug_at_ns && unplug_at_ns < t) t = unplug_at_ns;
      now_ns = std::max(now_ns, t);
      if (!fd_alive(fd)) {
        *revents = POLLERR;
        return 1;
      }
      produce();
    }
    if (done_.empty()) return 0;
    *revents = POLLIN;
    return 1;
  }
  int64_t monotonic_ns() override { return now_ns; }
  void sleep_ns(int64_t ns) override { now_ns += std::max<int64_t>(0, ns); }
  std::vector<std::string> list_video_devices() override { return {"/dev/video0", "/dev/video1"}; }

  int ioctl(int fd, unsigned long req, void* arg) override {
    if (fd == meta_fd_) return meta_ioctl(req, arg);
    if (!fd_alive(fd)) {
      errno = ENODEV;
      return -1;
    }
    switch (req) {
      case VIDIOC_QUERYCAP: {
        auto* c = static_cast<v4l2_capability*>(arg);
        *c = {};
        // snprintf with the field's own size: GCC's -Wstringop-overflow cannot prove strcpy
        // safe once the ioctl argument has been seen as other structs in this switch.
        std::snprintf(reinterpret_cast<char*>(c->driver), sizeof(c->driver), "%s", "uvcvideo");
        std::snprintf(reinterpret_cast<char*>(c->card), sizeof(c->card), "%s", "Fake UVC Camera");
        std::snprintf(reinterpret_cast<char*>(c->bus_info), sizeof(c->bus_info), "%s",
                      "usb-fake-1");
        c->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
        c->capabilities = c->device_caps | V4L2_CAP_DEVICE_CAPS;
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* d = static_cast<v4l2_fmtdesc*>(arg);
        if (d->index >= formats.size()) return fail(EINVAL);
        d->pixelformat = formats[d->index];
        std::snprintf(reinterpret_cast<char*>(d->description), sizeof(d->description), "%s",
                      d->pixelformat == V4L2_PIX_FMT_MJPEG ? "Motion-JPEG" : "YUYV 4:2:2");
        return 0;
      }
      case VIDIOC_S_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        bool offered = false;
        for (uint32_t x : formats) offered = offered || x == f->fmt.pix.pixelformat;
        if (!offered) f->fmt.pix.pixelformat = formats.front();  // like drivers: pick another
        active_format = f->fmt.pix.pixelformat;
        f->fmt.pix.width = static_cast<uint32_t>(width);  // one size only, like a cheap camera
        f->fmt.pix.height = static_cast<uint32_t>(height);
        f->fmt.pix.bytesperline =
            active_format == V4L2_PIX_FMT_YUYV ? static_cast<uint32_t>(width) * 2 : 0;
        return 0;
      }
      case VIDIOC_G_PARM: {
        auto* p = static_cast<v4l2_streamparm*>(arg);
        p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
        p->parm.capture.timeperframe = timeperframe;
        return 0;
      }
      case VIDIOC_S_PARM: {
        auto* p = static_cast<v4l2_streamparm*>(arg);
        // Only 30 and 15 fps exist; the driver picks the nearest.
        const auto& t = p->parm.capture.timeperframe;
        const double fps = t.numerator ? static_cast<double>(t.denominator) / t.numerator : 30;
        timeperframe = fps > 22.5 ? v4l2_fract{1, 30} : v4l2_fract{1, 15};
        period_ns = 1000000000LL * timeperframe.numerator / timeperframe.denominator;
        p->parm.capture.timeperframe = timeperframe;
        return 0;
      }
      case VIDIOC_QUERYCTRL: {
        auto* q = static_cast<v4l2_queryctrl*>(arg);
        if (q->id == V4L2_CID_EXPOSURE_AUTO) {
          q->minimum = 0;
          q->maximum = 3;
          return 0;
        }
        if (q->id == V4L2_CID_EXPOSURE_ABSOLUTE) {
          q->minimum = 3;
          q->maximum = 2047;
          q->step = 1;
          return 0;
        }
        if (q->id == V4L2_CID_GAIN) {
          q->minimum = 0;
          q->maximum = 255;
          q->step = 1;
          return 0;
        }
        return fail(EINVAL);  // no white balance on this camera
      }
      case VIDIOC_S_CTRL: {
        auto* c = static_cast<v4l2_control*>(arg);
        controls_set[c->id] = c->value;
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* r = static_cast<v4l2_requestbuffers*>(arg);
        if (r->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
        if (streaming_) return fail(EBUSY);
        r->count = std::min<uint32_t>(r->count, 8);  // drivers cap the count
        size_t max_payload = static_cast<size_t>(width) * height * 2;
        for (const auto& p : payloads[active_format]) max_payload = std::max(max_payload, p.size());
        storage_.assign(r->count, std::vector<uint8_t>(max_payload));
        queued_.clear();
        done_.clear();
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= storage_.size()) return fail(EINVAL);
        b->length = static_cast<uint32_t>(storage_[b->index].size());
        b->m.offset = static_cast<uint32_t>(b->index * kOffsetStep);
        return 0;
      }
      case VIDIOC_QBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= storage_.size()) return fail(EINVAL);
        queued_.push_back(b->index);
        return 0;
      }
      case VIDIOC_STREAMON:
        streaming_ = true;
        next_frame_ns_ = now_ns + period_ns;
        return 0;
      case VIDIOC_STREAMOFF:
        streaming_ = false;
        return 0;
      case VIDIOC_DQBUF: {
        produce();
        if (done_.empty()) return fail(EAGAIN);
        Done d = done_.front();
        done_.pop_front();
        if (eio_frames.count(d.seq)) {
          eio_frames.erase(d.seq);
          queued_.push_back(d.index);
          return fail(EIO);
        }
        auto* b = static_cast<v4l2_buffer*>(arg);
        b->index = d.index;
        b->bytesused = d.bytes;
        b->sequence = d.seq;
        b->flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_SOE |
                   (error_flag_frames.count(d.seq) ? V4L2_BUF_FLAG_ERROR : 0);
        b->timestamp.tv_sec = static_cast<time_t>(d.stamp_ns / 1000000000LL);
        b->timestamp.tv_usec = static_cast<suseconds_t>((d.stamp_ns % 1000000000LL) / 1000);
        return 0;
      }
      case VIDIOC_ENUM_FRAMESIZES: {
        auto* s = static_cast<v4l2_frmsizeenum*>(arg);
        if (s->index > 1) return fail(EINVAL);
        s->type = V4L2_FRMSIZE_TYPE_DISCRETE;
        s->discrete.width = s->index == 0 ? static_cast<uint32_t>(width) : 320;
        s->discrete.height = s->index == 0 ? static_cast<uint32_t>(height) : 240;
        return 0;
      }
      case VIDIOC_ENUM_FRAMEINTERVALS: {
        auto* iv = static_cast<v4l2_frmivalenum*>(arg);
        if (iv->index > 1) return fail(EINVAL);
        iv->type = V4L2_FRMIVAL_TYPE_DISCRETE;
        iv->discrete = iv->index == 0 ? v4l2_fract{1, 15} : v4l2_fract{1, 30};
        return 0;
      }
      default:
        return fail(ENOTTY);
    }
  }

  // The simulated time at which frame `seq` was received (its kernel timestamp).
  int64_t frame_stamp(uint32_t seq) const { return stamp_of_.at(seq); }
  // Lets time pass without reading (a slow consumer).
  void advance(int64_t ns) {
    now_ns += ns;
    produce();
  }

 private:
  static constexpr size_t kOffsetStep = 1 << 24;
  struct Done {
    uint32_t index, seq, bytes;
    int64_t stamp_ns;
  };

  static int fail(int e) {
    errno = e;
    return -1;
  }
  bool present() const {
    if (unplug_at_ns < 0 || now_ns < unplug_at_ns) return true;
    return replug_at_ns >= 0 && now_ns >= replug_at_ns;
  }
  // After an unplug a descriptor opened before it stays dead even once the device is back.
  bool fd_alive(int fd) const {
    if (fd != fd_ || !present()) return false;
    return !(unplug_at_ns >= 0 && now_ns >= unplug_at_ns && fd_opened_ns_ < unplug_at_ns);
  }

  // Frames due by now: filled into queued buffers, or dropped when none is queued.
  void produce() {
    if (!streaming_ || paused) {
      if (streaming_) next_frame_ns_ = std::max(next_frame_ns_, now_ns);
      return;
    }
    while (next_frame_ns_ <= now_ns) {
      const uint32_t seq = kseq_++;
      stamp_of_[seq] = next_frame_ns_;
      if (!queued_.empty()) {
        const uint32_t idx = queued_.front();
        queued_.pop_front();
        const auto& list = payloads[active_format];
        const auto& p = list[seq % list.size()];
        size_t n = std::min(p.size(), storage_[idx].size());
        std::memcpy(storage_[idx].data(), p.data(), n);
        if (truncate_frames.count(seq)) n = n * 4 / 10;
        done_.push_back({idx, seq, static_cast<uint32_t>(n), next_frame_ns_});
      }
      next_frame_ns_ += period_ns;
    }
  }

  int open_meta() {
    meta_fd_ = 50;
    ++open_fds;
    return meta_fd_;
  }
  int meta_ioctl(unsigned long req, void* arg) {
    if (req != VIDIOC_QUERYCAP) return fail(ENOTTY);
    auto* c = static_cast<v4l2_capability*>(arg);
    *c = {};
    std::snprintf(reinterpret_cast<char*>(c->driver), sizeof(c->driver), "%s", "uvcvideo");
    std::snprintf(reinterpret_cast<char*>(c->card), sizeof(c->card), "%s", "Fake UVC Camera");
    c->device_caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
    c->capabilities = c->device_caps | V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_DEVICE_CAPS;
    return 0;
  }

  int fd_ = -1;
  int meta_fd_ = -1;
  int64_t fd_opened_ns_ = 0;
  bool streaming_ = false;
  int64_t next_frame_ns_ = 0;
  uint32_t kseq_ = 0;
  std::vector<std::vector<uint8_t>> storage_;
  std::deque<uint32_t> queued_;
  std::deque<Done> done_;
  std::map<uint32_t, int64_t> stamp_of_;
};

}  // namespace rdslam::testing
