#include "drivers/v4l2_source.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/log.h"
#include "drivers/mjpeg_decoder.h"
#include "drivers/v4l2_syscalls.h"
#include "drivers/yuyv.h"

namespace rdslam {

void V4l2Params::visit(ParamVisitor& v) {
  v.field("pixel_format", pixel_format, {"auto", "mjpeg", "yuyv", "grey"},
          "camera format: auto = MJPEG if offered, else YUYV, else GREY");
  v.field("output", output, {"grey", "bgr"}, "image delivered to the pipeline");
  v.field("width", width, 0, 8192, "requested width in pixels; 0 = camera.width");
  v.field("height", height, 0, 8192, "requested height in pixels; 0 = camera.height");
  v.field("fps", fps, 1.0, 1000.0, "requested frame rate (VIDIOC_S_PARM)");
  v.field("buffers", buffers, 2, 32, "mmap streaming buffers (kernel queue depth)");
  v.field("exposure_us", exposure_us, -1, 10000000,
          "-1 leave as is, 0 auto exposure, > 0 manual exposure time in microseconds");
  v.field("gain", gain, -1, 100000, "-1 leave as is, >= 0 manual gain in driver units");
  v.field("white_balance_k", white_balance_k, -1, 15000,
          "-1 leave as is, 0 auto white balance, > 0 manual colour temperature in kelvin");
  v.field("stamp_offset_ms", stamp_offset_ms, -1000.0, 1000.0,
          "subtracted from the kernel (driver receipt) timestamp to estimate capture time");
  v.field("newest_only", newest_only,
          "deliver the newest queued frame and skip older ones (low latency)");
  v.field("mjpeg_strict", mjpeg_strict,
          "reject MJPEG frames with libjpeg warnings (truncated transfers)");
  v.field("reopen_backoff_ms", reopen_backoff_ms, 1, 60000,
          "first reopen delay after the camera disappears");
  v.field("reopen_backoff_max_ms", reopen_backoff_max_ms, 1, 600000,
          "reopen delay doubles up to this");
}

std::string V4l2Params::validate() const {
  if ((width == 0) != (height == 0)) {
    return "v4l2.width/v4l2.height: set both or neither (0 = camera size)";
  }
  if (width % 2 != 0) return "v4l2.width: must be even (YUYV packs pixel pairs)";
  if (reopen_backoff_max_ms < reopen_backoff_ms) {
    return "v4l2.reopen_backoff_max_ms: must be >= v4l2.reopen_backoff_ms";
  }
  return "";
}

namespace {

constexpr int kMaxBuffers = 32;

std::string fourcc_str(uint32_t f) {
  char s[5] = {static_cast<char>(f & 0xFF), static_cast<char>((f >> 8) & 0xFF),
               static_cast<char>((f >> 16) & 0xFF), static_cast<char>((f >> 24) & 0xFF), 0};
  for (int i = 0; i < 4; ++i) {
    if (s[i] < 32 || s[i] > 126) s[i] = '?';
  }
  return s;
}

bool usable_fourcc(uint32_t f) {
  return f == V4L2_PIX_FMT_MJPEG || f == V4L2_PIX_FMT_YUYV || f == V4L2_PIX_FMT_GREY;
}

std::string cstr(const uint8_t* s, size_t n) {
  return std::string(reinterpret_cast<const char*>(s),
                     strnlen(reinterpret_cast<const char*>(s), n));
}

// Capabilities of this node (device_caps when the driver reports per-node caps: a UVC
// camera exposes a second, metadata-only node).
uint32_t node_caps(const v4l2_capability& cap) {
  return (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
}

}  // namespace

struct V4l2Source::Impl {
  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
  };

  Impl(V4l2Syscalls& s, const V4l2Params& p) : sys(s), params(p), decoder(p.mjpeg_strict) {}

  V4l2Syscalls& sys;
  V4l2Params params;
  std::string device;
  MjpegDecoder decoder;

  int fd = -1;
  std::array<Buffer, kMaxBuffers> buffers{};
  int buffer_count = 0;
  bool streaming = false;

  // Negotiated at first open; a reopen must give the same or it is refused.
  uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  uint32_t bytesperline = 0;
  double fps = 0.0;
  int out_type = CV_8UC1;

  // Streaming state machine: kStreaming <-> kLost (closed, reopening with backoff).
  bool lost = false;
  int64_t next_reopen_ns = 0;
  int64_t backoff_ns = 0;
  bool have_kernel_seq = false;
  uint32_t last_kernel_seq = 0;
  uint64_t next_seq = 0;

  std::atomic<uint64_t> delivered{0}, faults{0}, reopens{0}, timeouts{0};
  std::atomic<uint64_t> corrupt{0}, device_lost{0}, reopened{0}, kernel_dropped{0},
      stale_skipped{0};

  // ---- open / close ----

  // Returns an empty string on success, otherwise why it failed (and everything closed).
  // `first`: negotiate; otherwise insist on the format negotiated the first time.
  std::string open_device(bool first, std::vector<std::string>* control_report);
  std::string negotiate(bool first);
  void apply_controls(std::vector<std::string>* report);
  void set_control(uint32_t id, int32_t value, const char* what, std::vector<std::string>* report);
  std::string start_streaming();
  void close_device();
  void mark_lost(int err, const char* where);
  bool requeue(const v4l2_buffer& b);
  // Counts gaps in the driver's frame sequence (frames it dropped for want of a buffer).
  void track_sequence(const v4l2_buffer& b) {
    if (have_kernel_seq && b.sequence > last_kernel_seq + 1) {
      kernel_dropped.fetch_add(b.sequence - last_kernel_seq - 1, std::memory_order_relaxed);
    }
    have_kernel_seq = true;
    last_kernel_seq = b.sequence;
  }
  SourceStatus convert(const v4l2_buffer& b, Frame& out);
};

std::string V4l2Source::Impl::open_device(bool first, std::vector<std::string>* control_report) {
  // O_NONBLOCK: DQBUF returns EAGAIN instead of blocking, so poll() owns all waiting and
  // the caller's timeout is honoured exactly.
  fd = sys.open(device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::string("open: ") + std::strerror(errno);
  v4l2_capability cap{};
  if (xioctl(sys, fd, VIDIOC_QUERYCAP, &cap) != 0) {
    const std::string e =
        std::string("VIDIOC_QUERYCAP: ") + std::strerror(errno) + " (not a V4L2 device?)";
    close_device();
    return e;
  }
  const uint32_t caps = node_caps(cap);
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    close_device();
    return "not a video capture node (a UVC camera's second node carries metadata only)";
  }
  if (!(caps & V4L2_CAP_STREAMING)) {
    close_device();
    return "driver has no streaming (mmap) I/O";
  }
  std::string e = negotiate(first);
  if (e.empty()) {
    apply_controls(control_report);
    e = start_streaming();
  }
  if (!e.empty()) close_device();
  return e;
}

std::string V4l2Source::Impl::negotiate(bool first) {
  // Formats the camera offers.
  bool has_mjpeg = false, has_yuyv = false, has_grey = false;
  std::string offered;
  for (uint32_t i = 0; i < 64; ++i) {
    v4l2_fmtdesc d{};
    d.index = i;
    d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(sys, fd, VIDIOC_ENUM_FMT, &d) != 0) break;
    has_mjpeg |= d.pixelformat == V4L2_PIX_FMT_MJPEG;
    has_yuyv |= d.pixelformat == V4L2_PIX_FMT_YUYV;
    has_grey |= d.pixelformat == V4L2_PIX_FMT_GREY;
    if (first) offered += (offered.empty() ? "" : " ") + fourcc_str(d.pixelformat);
  }
  uint32_t want = fourcc;
  if (first) {
    // MJPEG first: YUYV 640x480 at 30 fps is 18 MB/s, most of a USB 2.0 bus, and larger
    // sizes only come at low frame rates; MJPEG is ~10x smaller and decodes fast.
    const std::string& pf = params.pixel_format;
    if (pf == "mjpeg" || (pf == "auto" && has_mjpeg)) {
      want = has_mjpeg ? V4L2_PIX_FMT_MJPEG : 0;
    } else if (pf == "yuyv" || (pf == "auto" && has_yuyv)) {
      want = has_yuyv ? V4L2_PIX_FMT_YUYV : 0;
    } else if (pf == "grey" || pf == "auto") {
      want = has_grey ? V4L2_PIX_FMT_GREY : 0;
    }
    if (want == 0) {
      return "no usable pixel format (v4l2.pixel_format=" + pf +
             "; camera offers: " + (offered.empty() ? std::string("nothing") : offered) +
             "; rdslam decodes MJPG, YUYV, GREY)";
    }
  } else if ((want == V4L2_PIX_FMT_MJPEG && !has_mjpeg) ||
             (want == V4L2_PIX_FMT_YUYV && !has_yuyv) || (want == V4L2_PIX_FMT_GREY && !has_grey)) {
    return "reopened device no longer offers " + fourcc_str(want);
  }

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<uint32_t>(width);
  fmt.fmt.pix.height = static_cast<uint32_t>(height);
  fmt.fmt.pix.pixelformat = want;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(sys, fd, VIDIOC_S_FMT, &fmt) != 0) {
    return std::string("VIDIOC_S_FMT: ") + std::strerror(errno);
  }
  if (fmt.fmt.pix.pixelformat != want) {
    return "driver refused " + fourcc_str(want) + " and chose " +
           fourcc_str(fmt.fmt.pix.pixelformat);
  }
  const int got_w = static_cast<int>(fmt.fmt.pix.width);
  const int got_h = static_cast<int>(fmt.fmt.pix.height);
  if (first) {
    if (got_w != width || got_h != height) {
      // The driver picks the nearest size it supports; intrinsics must match what arrives.
      RDSLAM_LOG_WARN("v4l2 %s: requested %dx%d, camera delivers %dx%d (set camera.* to match)",
                      device.c_str(), width, height, got_w, got_h);
    }
    if (got_w <= 0 || got_h <= 0 || (want == V4L2_PIX_FMT_YUYV && got_w % 2 != 0)) {
      return "driver negotiated an unusable size " + std::to_string(got_w) + "x" +
             std::to_string(got_h);
    }
    width = got_w;
    height = got_h;
    fourcc = want;
  } else if (got_w != width || got_h != height) {
    return "reopened device negotiated " + std::to_string(got_w) + "x" + std::to_string(got_h) +
           " instead of " + std::to_string(width) + "x" + std::to_string(height);
  }
  bytesperline = fmt.fmt.pix.bytesperline;
  if (fourcc == V4L2_PIX_FMT_YUYV && bytesperline < static_cast<uint32_t>(width) * 2) {
    bytesperline = static_cast<uint32_t>(width) * 2;
  }
  if (fourcc == V4L2_PIX_FMT_GREY && bytesperline < static_cast<uint32_t>(width)) {
    bytesperline = static_cast<uint32_t>(width);
  }

  // Frame rate: VIDIOC_S_PARM with timeperframe = 1/fps when the driver supports it.
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(sys, fd, VIDIOC_G_PARM, &parm) == 0 &&
      (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator =
        static_cast<uint32_t>(std::lround(params.fps * 1000.0));
    if (xioctl(sys, fd, VIDIOC_S_PARM, &parm) != 0) {
      RDSLAM_LOG_WARN("v4l2 %s: VIDIOC_S_PARM %.3g fps failed: %s", device.c_str(), params.fps,
                      std::strerror(errno));
    }
    const v4l2_fract tpf = parm.parm.capture.timeperframe;
    if (tpf.numerator > 0 && tpf.denominator > 0) {
      fps = static_cast<double>(tpf.denominator) / tpf.numerator;
    }
    if (first && std::fabs(fps - params.fps) > 0.01 * params.fps) {
      RDSLAM_LOG_WARN("v4l2 %s: requested %.3g fps, camera runs at %.3g fps", device.c_str(),
                      params.fps, fps);
    }
  } else if (first) {
    RDSLAM_LOG_WARN("v4l2 %s: driver cannot set the frame rate; it runs at its own",
                    device.c_str());
    fps = 0.0;
  }
  return "";
}

void V4l2Source::Impl::set_control(uint32_t id, int32_t value, const char* what,
                                   std::vector<std::string>* report) {
  char line[200];
  v4l2_queryctrl q{};
  q.id = id;
  if (xioctl(sys, fd, VIDIOC_QUERYCTRL, &q) != 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) {
    std::snprintf(line, sizeof(line), "%s: not supported by this camera", what);
  } else {
    int32_t v = std::clamp(value, q.minimum, q.maximum);
    if (q.step > 1) v = q.minimum + (v - q.minimum) / q.step * q.step;
    v4l2_control c{};
    c.id = id;
    c.value = v;
    if (xioctl(sys, fd, VIDIOC_S_CTRL, &c) != 0) {
      std::snprintf(line, sizeof(line), "%s=%d: VIDIOC_S_CTRL failed: %s", what, v,
                    std::strerror(errno));
    } else if (v != value) {
      std::snprintf(line, sizeof(line), "%s=%d (clamped from %d to the camera's range [%d, %d])",
                    what, v, value, q.minimum, q.maximum);
    } else {
      std::snprintf(line, sizeof(line), "%s=%d", what, v);
    }
  }
  // Controls are applied again after every reopen (a replugged camera starts from its
  // defaults); only the first time is logged at info level and kept for the report.
  if (report) {
    RDSLAM_LOG_INFO("v4l2 %s: control %s", device.c_str(), line);
    report->emplace_back(line);
  } else {
    RDSLAM_LOG_DEBUG("v4l2 %s: control %s", device.c_str(), line);
  }
}

void V4l2Source::Impl::apply_controls(std::vector<std::string>* report) {
  // Exposure: UVC cameras offer "aperture priority" as their auto mode, others "auto".
  if (params.exposure_us == 0) {
    v4l2_queryctrl q{};
    q.id = V4L2_CID_EXPOSURE_AUTO;
    int32_t mode = V4L2_EXPOSURE_APERTURE_PRIORITY;
    if (xioctl(sys, fd, VIDIOC_QUERYCTRL, &q) == 0 && q.maximum < V4L2_EXPOSURE_APERTURE_PRIORITY) {
      mode = V4L2_EXPOSURE_AUTO;
    }
    set_control(V4L2_CID_EXPOSURE_AUTO, mode, "exposure_auto", report);
  } else if (params.exposure_us > 0) {
    // Fixed exposure keeps brightness constant between frames, which the tracker's patch
    // matching prefers; V4L2_CID_EXPOSURE_ABSOLUTE is in units of 100 us.
    set_control(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "exposure_auto(manual)", report);
    set_control(V4L2_CID_EXPOSURE_ABSOLUTE, std::max(1, (params.exposure_us + 50) / 100),
                "exposure_absolute(100us)", report);
  }
  if (params.gain >= 0) {
    v4l2_queryctrl q{};
    q.id = V4L2_CID_AUTOGAIN;
    if (xioctl(sys, fd, VIDIOC_QUERYCTRL, &q) == 0 && !(q.flags & V4L2_CTRL_FLAG_DISABLED)) {
      set_control(V4L2_CID_AUTOGAIN, 0, "autogain", report);
    }
    set_control(V4L2_CID_GAIN, params.gain, "gain", report);
  }
  if (params.white_balance_k == 0) {
    set_control(V4L2_CID_AUTO_WHITE_BALANCE, 1, "white_balance_auto", report);
  } else if (params.white_balance_k > 0) {
    set_control(V4L2_CID_AUTO_WHITE_BALANCE, 0, "white_balance_auto", report);
    set_control(V4L2_CID_WHITE_BALANCE_TEMPERATURE, params.white_balance_k,
                "white_balance_temperature(K)", report);
  }
}

std::string V4l2Source::Impl::start_streaming() {
  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(params.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(sys, fd, VIDIOC_REQBUFS, &req) != 0) {
    return std::string("VIDIOC_REQBUFS: ") + std::strerror(errno);
  }
  if (req.count < 2 || req.count > static_cast<uint32_t>(kMaxBuffers)) {
    return "driver granted " + std::to_string(req.count) + " buffers (need 2.." +
           std::to_string(kMaxBuffers) + ")";
  }
  buffer_count = static_cast<int>(req.count);
  for (int i = 0; i < buffer_count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = static_cast<uint32_t>(i);
    if (xioctl(sys, fd, VIDIOC_QUERYBUF, &b) != 0) {
      return std::string("VIDIOC_QUERYBUF: ") + std::strerror(errno);
    }
    void* p = sys.mmap(b.length, fd, static_cast<off_t>(b.m.offset));
    if (p == MAP_FAILED) return std::string("mmap: ") + std::strerror(errno);
    buffers[i].start = p;
    buffers[i].length = b.length;
  }
  for (int i = 0; i < buffer_count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = static_cast<uint32_t>(i);
    if (xioctl(sys, fd, VIDIOC_QBUF, &b) != 0) {
      return std::string("VIDIOC_QBUF: ") + std::strerror(errno);
    }
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(sys, fd, VIDIOC_STREAMON, &type) != 0) {
    return std::string("VIDIOC_STREAMON: ") + std::strerror(errno);
  }
  streaming = true;
  have_kernel_seq = false;
  return "";
}

void V4l2Source::Impl::close_device() {
  if (fd >= 0 && streaming) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(sys, fd, VIDIOC_STREAMOFF, &type);  // fails harmlessly on an unplugged device
  }
  streaming = false;
  for (int i = 0; i < kMaxBuffers; ++i) {
    if (buffers[i].start) sys.munmap(buffers[i].start, buffers[i].length);
    buffers[i] = Buffer{};
  }
  buffer_count = 0;
  if (fd >= 0) sys.close(fd);
  fd = -1;
}

void V4l2Source::Impl::mark_lost(int err, const char* where) {
  RDSLAM_LOG_WARN("v4l2 %s: device lost (%s: %s); reopening with backoff", device.c_str(), where,
                  std::strerror(err));
  close_device();
  lost = true;
  device_lost.fetch_add(1, std::memory_order_relaxed);
  faults.fetch_add(1, std::memory_order_relaxed);
  backoff_ns = static_cast<int64_t>(params.reopen_backoff_ms) * 1000000LL;
  next_reopen_ns = sys.monotonic_ns() + backoff_ns;
}

bool V4l2Source::Impl::requeue(const v4l2_buffer& b) {
  v4l2_buffer q{};
  q.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  q.memory = V4L2_MEMORY_MMAP;
  q.index = b.index;
  if (xioctl(sys, fd, VIDIOC_QBUF, &q) == 0) return true;
  mark_lost(errno, "VIDIOC_QBUF");
  return false;
}

SourceStatus V4l2Source::Impl::convert(const v4l2_buffer& b, Frame& out) {
  const uint8_t* data = static_cast<const uint8_t*>(buffers[b.index].start);
  const size_t bytes = std::min<size_t>(b.bytesused, buffers[b.index].length);
  bool ok = false;
  if (fourcc == V4L2_PIX_FMT_MJPEG) {
    const DecodeStatus s = decoder.decode(data, bytes, out.image);
    ok = s == DecodeStatus::kOk;
    if (!ok) {
      RDSLAM_LOG_DEBUG("v4l2 %s: MJPEG frame skipped (%s: %s)", device.c_str(), to_string(s),
                       decoder.last_error());
    }
  } else if (fourcc == V4L2_PIX_FMT_YUYV) {
    ok = yuyv_to_image(data, bytes, width, height, bytesperline, out.image);
  } else if (fourcc == V4L2_PIX_FMT_GREY) {
    const size_t need = static_cast<size_t>(bytesperline) * (height - 1) + width;
    if (bytes >= need) {
      const cv::Mat src(height, width, CV_8UC1, const_cast<uint8_t*>(data), bytesperline);
      if (out.image.type() == CV_8UC1) {
        src.copyTo(out.image);
      } else {
        cv::cvtColor(src, out.image, cv::COLOR_GRAY2BGR);  // same size/type: no realloc
      }
      ok = true;
    }
  }
  return ok ? SourceStatus::kOk : SourceStatus::kFault;
}

V4l2Source::V4l2Source(const std::string& device, const V4l2Params& params, int default_width,
                       int default_height, V4l2Syscalls& sys)
    : impl_(std::make_unique<Impl>(sys, params)) {
  const std::string bad = params.validate();
  if (!bad.empty()) throw std::runtime_error("v4l2:" + device + ": " + bad);
  Impl& m = *impl_;
  m.device = device;
  m.width = params.width > 0 ? params.width : default_width;
  m.height = params.height > 0 ? params.height : default_height;
  m.out_type = params.output == "bgr" ? CV_8UC3 : CV_8UC1;
  const std::string e = m.open_device(/*first=*/true, &control_report_);
  if (!e.empty()) throw std::runtime_error("v4l2:" + device + ": " + e);
  info_.uri = "v4l2:" + device;
  info_.kind = "v4l2";
  info_.width = m.width;
  info_.height = m.height;
  info_.format = m.out_type == CV_8UC3 ? PixelFormat::kBgr8 : PixelFormat::kGray8;
  info_.nominal_fps = m.fps;
  info_.live = true;
  info_.frame_count = -1;
  RDSLAM_LOG_INFO("v4l2 %s: streaming %s %dx%d at %.3g fps, %d buffers, output %s", device.c_str(),
                  fourcc_str(m.fourcc).c_str(), m.width, m.height, m.fps, m.buffer_count,
                  params.output.c_str());
}

V4l2Source::~V4l2Source() {
  impl_->close_device();
}

SourceCounters V4l2Source::counters() const {
  SourceCounters c;
  c.delivered = impl_->delivered.load(std::memory_order_relaxed);
  c.faults = impl_->faults.load(std::memory_order_relaxed);
  c.reopens = impl_->reopens.load(std::memory_order_relaxed);
  c.timeouts = impl_->timeouts.load(std::memory_order_relaxed);
  // Frames that existed but were never delivered because the reader came late: the stale
  // ones newest_only skipped, and those the driver dropped for want of a free buffer.
  c.skipped = impl_->stale_skipped.load(std::memory_order_relaxed) +
              impl_->kernel_dropped.load(std::memory_order_relaxed);
  return c;
}

V4l2Stats V4l2Source::stats() const {
  V4l2Stats s;
  s.corrupt = impl_->corrupt.load(std::memory_order_relaxed);
  s.device_lost = impl_->device_lost.load(std::memory_order_relaxed);
  s.reopened = impl_->reopened.load(std::memory_order_relaxed);
  s.kernel_dropped = impl_->kernel_dropped.load(std::memory_order_relaxed);
  s.stale_skipped = impl_->stale_skipped.load(std::memory_order_relaxed);
  return s;
}

std::string V4l2Source::fourcc() const {
  return fourcc_str(impl_->fourcc);
}

SourceStatus V4l2Source::read(Frame& out, int timeout_ms) {
  Impl& m = *impl_;
  // Sized once; later reads reuse the caller's buffer (no allocation per frame).
  if (out.image.rows != m.height || out.image.cols != m.width || out.image.type() != m.out_type) {
    out.image.create(m.height, m.width, m.out_type);
  }
  const int64_t deadline =
      m.sys.monotonic_ns() + static_cast<int64_t>(std::max(0, timeout_ms)) * 1000000LL;
  for (;;) {
    const int64_t now = m.sys.monotonic_ns();
    if (m.lost) {
      if (now >= m.next_reopen_ns) {
        m.reopens.fetch_add(1, std::memory_order_relaxed);
        const std::string e = m.open_device(/*first=*/false, nullptr);
        if (e.empty()) {
          m.lost = false;
          m.reopened.fetch_add(1, std::memory_order_relaxed);
          RDSLAM_LOG_INFO("v4l2 %s: reopened, streaming again", m.device.c_str());
          continue;
        }
        RDSLAM_LOG_DEBUG("v4l2 %s: reopen failed: %s", m.device.c_str(), e.c_str());
        m.backoff_ns = std::min<int64_t>(
            m.backoff_ns * 2, static_cast<int64_t>(m.params.reopen_backoff_max_ms) * 1000000LL);
        m.next_reopen_ns = m.sys.monotonic_ns() + m.backoff_ns;
      }
      const int64_t now2 = m.sys.monotonic_ns();
      if (now2 >= deadline) {
        m.timeouts.fetch_add(1, std::memory_order_relaxed);
        return SourceStatus::kTimeout;
      }
      m.sys.sleep_ns(std::min(deadline, m.next_reopen_ns) - now2);
      continue;
    }

    const int64_t remaining_ns = std::max<int64_t>(0, deadline - now);
    short revents = 0;
    const int pr =
        m.sys.poll(m.fd, POLLIN, &revents, static_cast<int>((remaining_ns + 999999) / 1000000));
    if (pr < 0) {
      if (errno == EINTR) continue;
      m.mark_lost(errno, "poll");
      return SourceStatus::kFault;
    }
    if (pr == 0) {
      m.timeouts.fetch_add(1, std::memory_order_relaxed);
      return SourceStatus::kTimeout;
    }

    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (xioctl(m.sys, m.fd, VIDIOC_DQBUF, &b) != 0) {
      const int err = errno;
      if (err == EAGAIN && !(revents & (POLLERR | POLLHUP | POLLNVAL))) continue;  // spurious
      // POLLERR with EAGAIN: uvcvideo signals a disconnect through poll before DQBUF fails.
      m.mark_lost(err == EAGAIN ? ENODEV : err, "VIDIOC_DQBUF");
      return SourceStatus::kFault;
    }
    m.track_sequence(b);
    // newest_only: older frames waiting in the kernel queue are stale for a tracker that
    // fell behind; hand back the newest and count the rest (like a live camera would drop).
    while (m.params.newest_only) {
      v4l2_buffer newer{};
      newer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      newer.memory = V4L2_MEMORY_MMAP;
      if (xioctl(m.sys, m.fd, VIDIOC_DQBUF, &newer) != 0) break;  // EAGAIN: b is the newest
      m.track_sequence(newer);
      if (!m.requeue(b)) return SourceStatus::kFault;
      m.stale_skipped.fetch_add(1, std::memory_order_relaxed);
      b = newer;
    }
    const int64_t arrival = m.sys.monotonic_ns();

    SourceStatus st = SourceStatus::kFault;
    if (b.index >= static_cast<uint32_t>(m.buffer_count)) {
      st = SourceStatus::kFault;  // a driver bug; never index out of the mapping table
    } else if (b.flags & V4L2_BUF_FLAG_ERROR) {
      st = SourceStatus::kFault;  // the driver knows the frame is damaged
    } else {
      st = m.convert(b, out);
    }
    if (st != SourceStatus::kOk) {
      m.corrupt.fetch_add(1, std::memory_order_relaxed);
      m.faults.fetch_add(1, std::memory_order_relaxed);
      if (b.index < static_cast<uint32_t>(m.buffer_count)) m.requeue(b);
      return SourceStatus::kFault;
    }
    int64_t stamp = arrival;
    if ((b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
      stamp = static_cast<int64_t>(b.timestamp.tv_sec) * 1000000000LL +
              static_cast<int64_t>(b.timestamp.tv_usec) * 1000LL;
    }
    out.stamp_ns = stamp - static_cast<int64_t>(std::llround(m.params.stamp_offset_ms * 1e6));
    out.arrival_mono_ns = arrival;
    out.format = m.out_type == CV_8UC3 ? PixelFormat::kBgr8 : PixelFormat::kGray8;
    out.seq = m.next_seq++;
    out.dataset_index = -1;
    m.delivered.fetch_add(1, std::memory_order_relaxed);
    // The frame is already converted, so a failed requeue (unplug right now) still delivers
    // it; the next read() starts the reopen cycle.
    m.requeue(b);
    return SourceStatus::kOk;
  }
}

std::unique_ptr<FrameSource> open_v4l2_source(const std::string& device, const V4l2Params& params,
                                              int default_width, int default_height) {
  return std::make_unique<V4l2Source>(device, params, default_width, default_height, system_v4l2());
}

// ---- listing ----

namespace {

std::string fps_text(const v4l2_fract& f) {
  char s[32];
  std::snprintf(s, sizeof(s), "%.4g",
                f.numerator ? static_cast<double>(f.denominator) / f.numerator : 0.0);
  return s;
}

void list_intervals(V4l2Syscalls& sys, int fd, uint32_t fourcc, V4l2SizeInfo& size) {
  for (uint32_t i = 0; i < 256; ++i) {
    v4l2_frmivalenum iv{};
    iv.index = i;
    iv.pixel_format = fourcc;
    iv.width = static_cast<uint32_t>(size.width);
    iv.height = static_cast<uint32_t>(size.height);
    if (xioctl(sys, fd, VIDIOC_ENUM_FRAMEINTERVALS, &iv) != 0) break;
    if (iv.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
      if (iv.discrete.numerator > 0) {
        size.fps.push_back(static_cast<double>(iv.discrete.denominator) / iv.discrete.numerator);
      }
    } else {
      // Interval range: the fastest rate has the shortest interval (min).
      size.fps_range = fps_text(iv.stepwise.max) + ".." + fps_text(iv.stepwise.min) + " fps";
      break;
    }
  }
  std::sort(size.fps.begin(), size.fps.end(), std::greater<double>());
}

}  // namespace

std::vector<V4l2DeviceInfo> list_v4l2_devices(V4l2Syscalls& sys) {
  std::vector<V4l2DeviceInfo> out;
  for (const std::string& path : sys.list_video_devices()) {
    V4l2DeviceInfo dev;
    dev.path = path;
    const int fd = sys.open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
      dev.note = std::string("cannot open: ") + std::strerror(errno);
      out.push_back(std::move(dev));
      continue;
    }
    v4l2_capability cap{};
    if (xioctl(sys, fd, VIDIOC_QUERYCAP, &cap) != 0) {
      dev.note = std::string("VIDIOC_QUERYCAP: ") + std::strerror(errno);
      sys.close(fd);
      out.push_back(std::move(dev));
      continue;
    }
    dev.card = cstr(cap.card, sizeof(cap.card));
    dev.driver = cstr(cap.driver, sizeof(cap.driver));
    dev.bus = cstr(cap.bus_info, sizeof(cap.bus_info));
    const uint32_t caps = node_caps(cap);
    dev.capture = (caps & V4L2_CAP_VIDEO_CAPTURE) && (caps & V4L2_CAP_STREAMING);
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
      dev.note =
          (caps & V4L2_CAP_META_CAPTURE) ? "metadata node, not video" : "not a video capture node";
    } else if (!(caps & V4L2_CAP_STREAMING)) {
      dev.note = "no streaming (mmap) I/O";
    }
    for (uint32_t i = 0; dev.capture && i < 64; ++i) {
      v4l2_fmtdesc d{};
      d.index = i;
      d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (xioctl(sys, fd, VIDIOC_ENUM_FMT, &d) != 0) break;
      V4l2FormatInfo f;
      f.fourcc = fourcc_str(d.pixelformat);
      f.description = cstr(d.description, sizeof(d.description));
      f.usable = usable_fourcc(d.pixelformat);
      for (uint32_t j = 0; f.usable && j < 256; ++j) {
        v4l2_frmsizeenum fs{};
        fs.index = j;
        fs.pixel_format = d.pixelformat;
        if (xioctl(sys, fd, VIDIOC_ENUM_FRAMESIZES, &fs) != 0) break;
        if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
          V4l2SizeInfo s;
          s.width = static_cast<int>(fs.discrete.width);
          s.height = static_cast<int>(fs.discrete.height);
          list_intervals(sys, fd, d.pixelformat, s);
          f.sizes.push_back(std::move(s));
        } else {
          char r[96];
          std::snprintf(r, sizeof(r), "%ux%u..%ux%u step %ux%u", fs.stepwise.min_width,
                        fs.stepwise.min_height, fs.stepwise.max_width, fs.stepwise.max_height,
                        fs.stepwise.step_width, fs.stepwise.step_height);
          f.size_range = r;
          break;
        }
      }
      dev.formats.push_back(std::move(f));
    }
    if (dev.capture) {
      bool any = false;
      for (const auto& f : dev.formats) any = any || f.usable;
      if (!any) dev.note = "offers no format rdslam decodes (MJPG, YUYV, GREY)";
    }
    sys.close(fd);
    out.push_back(std::move(dev));
  }
  return out;
}

std::string describe_v4l2_devices(const std::vector<V4l2DeviceInfo>& devices) {
  std::string s;
  char line[512];
  int usable_devices = 0;
  for (const auto& d : devices) {
    std::snprintf(line, sizeof(line), "%s  %s  (%s%s%s)\n", d.path.c_str(),
                  d.card.empty() ? "?" : d.card.c_str(), d.driver.empty() ? "?" : d.driver.c_str(),
                  d.bus.empty() ? "" : ", ", d.bus.c_str());
    s += line;
    if (!d.note.empty()) {
      s += "    skipped: " + d.note + "\n";
      if (!d.capture) continue;
    }
    const V4l2SizeInfo* best = nullptr;
    const V4l2FormatInfo* best_fmt = nullptr;
    for (const auto& f : d.formats) {
      std::snprintf(line, sizeof(line), "    %-4s  %s%s\n", f.fourcc.c_str(), f.description.c_str(),
                    f.usable ? "" : "  (not decoded by rdslam)");
      s += line;
      if (!f.size_range.empty()) s += "          sizes " + f.size_range + "\n";
      for (const auto& z : f.sizes) {
        std::string rates;
        for (double r : z.fps) {
          std::snprintf(line, sizeof(line), "%s%.4g", rates.empty() ? "" : ", ", r);
          rates += line;
        }
        if (!z.fps_range.empty()) rates = z.fps_range;
        std::snprintf(line, sizeof(line), "          %5dx%-5d %s%s\n", z.width, z.height,
                      rates.empty() ? "(rate not reported)" : rates.c_str(),
                      z.fps.empty() ? "" : " fps");
        s += line;
        // Suggest the largest size at >= 30 fps in the preferred format (MJPEG first).
        const bool fast = !z.fps.empty() && z.fps.front() >= 29.9;
        const bool better_fmt = !best_fmt || (f.fourcc == "MJPG" && best_fmt->fourcc != "MJPG");
        if (f.usable && fast &&
            (better_fmt || (best_fmt == &f && z.width * z.height > best->width * best->height))) {
          best = &z;
          best_fmt = &f;
        }
      }
    }
    bool any_usable = false;
    for (const auto& f : d.formats) any_usable = any_usable || f.usable;
    if (d.capture && any_usable) {
      ++usable_devices;
      s += "    use: --set source=v4l2:" + d.path;
      if (best) {
        std::snprintf(line, sizeof(line),
                      " --set v4l2.pixel_format=%s --set v4l2.width=%d --set v4l2.height=%d",
                      best_fmt->fourcc == "MJPG"   ? "mjpeg"
                      : best_fmt->fourcc == "YUYV" ? "yuyv"
                                                   : "grey",
                      best->width, best->height);
        s += line;
      }
      s += "\n";
    }
  }
  if (usable_devices == 0) {
    s += devices.empty() ? "no V4L2 video devices (/dev/video*) on this machine.\n"
                         : "no V4L2 device here offers a format rdslam can use.\n";
    s += "Plug in a USB (UVC) camera, check `ls -l /dev/video*` and that this user is in the "
         "'video' group; test rigs can load vivid or v4l2loopback (docs/cameras.md).\n";
  }
  return s;
}

}  // namespace rdslam
