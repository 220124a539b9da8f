#include "drivers/lcm_image_source.h"

#include <time.h>

#include <bot_core/image_t.hpp>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/log.h"

namespace rdslam {

namespace {

// LCM encodes integers big-endian.
uint64_t be64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}
int32_t be32(const uint8_t* p) {
  return static_cast<int32_t>((static_cast<uint32_t>(p[0]) << 24) |
                              (static_cast<uint32_t>(p[1]) << 16) |
                              (static_cast<uint32_t>(p[2]) << 8) | static_cast<uint32_t>(p[3]));
}

// Bytes a packed image of `width` pixels per row and `rows` rows needs with this stride.
bool fits(int64_t size, int32_t stride, int32_t row_bytes, int32_t rows) {
  return stride >= row_bytes && size >= static_cast<int64_t>(stride) * (rows - 1) + row_bytes;
}

}  // namespace

bool parse_bot_core_image(const uint8_t* buf, size_t len, ImageMsgView& out) {
  // hash(8) utime(8) width(4) height(4) row_stride(4) pixelformat(4) size(4) data(size)
  // nmetadata(4) metadata[nmetadata] {key: int32 length incl. NUL + bytes, n(4), value(n)}.
  // The metadata is not used, but its bounds are checked: a truncated message is rejected.
  constexpr size_t kHeader = 8 + 8 + 5 * 4;
  if (buf == nullptr || len < kHeader + 4) return false;
  if (be64(buf) != static_cast<uint64_t>(bot_core::image_t::getHash())) return false;
  out.utime = static_cast<int64_t>(be64(buf + 8));
  out.width = be32(buf + 16);
  out.height = be32(buf + 20);
  out.row_stride = be32(buf + 24);
  out.pixelformat = be32(buf + 28);
  out.size = be32(buf + 32);
  if (out.size < 0 || static_cast<size_t>(out.size) > len - kHeader - 4) return false;
  if (out.width <= 0 || out.height <= 0 || out.width > 16384 || out.height > 16384) return false;
  out.data = buf + kHeader;
  size_t pos = kHeader + static_cast<size_t>(out.size);
  const int32_t nmeta = be32(buf + pos);
  pos += 4;
  if (nmeta < 0) return false;
  for (int32_t i = 0; i < nmeta; ++i) {
    if (len - pos < 4) return false;
    const int32_t key_len = be32(buf + pos);
    pos += 4;
    if (key_len < 1 || static_cast<size_t>(key_len) > len - pos) return false;
    pos += static_cast<size_t>(key_len);
    if (len - pos < 4) return false;
    const int32_t n = be32(buf + pos);
    pos += 4;
    if (n < 0 || static_cast<size_t>(n) > len - pos) return false;
    pos += static_cast<size_t>(n);
  }
  return true;
}

LcmImageSource::LcmImageSource(std::string uri, std::string channel, const std::string& url,
                               int width, int height, PixelFormat format)
    : channel_(std::move(channel)), lcm_(url) {
  if (!lcm_.good()) throw std::runtime_error(uri + ": cannot initialise LCM with url " + url);
  if (width <= 0 || height <= 0) throw std::runtime_error(uri + ": frame size must be positive");
  info_.uri = std::move(uri);
  info_.kind = "lcm";
  info_.width = width;
  info_.height = height;
  info_.format = format;
  info_.live = true;
  // Worst case payload: uncompressed BGR with some row padding. Reserved now so that the
  // handler does not grow the buffer while frames flow.
  pending_bytes_.reserve(static_cast<size_t>(width) * height * 4);
  if (lcm_subscribe(lcm_.getUnderlyingLCM(), channel_.c_str(), &LcmImageSource::on_message_c,
                    this) == nullptr) {
    throw std::runtime_error(info_.uri + ": cannot subscribe to channel " + channel_);
  }
}

void LcmImageSource::on_message_c(const lcm_recv_buf_t* rbuf, const char*, void* self) {
  static_cast<LcmImageSource*>(self)->on_message(static_cast<const uint8_t*>(rbuf->data),
                                                 rbuf->data_size);
}

void LcmImageSource::on_message(const uint8_t* data, size_t size) {
  ImageMsgView m;
  if (!parse_bot_core_image(data, size, m)) {
    ++counters_.faults;
    if (!warned_) {
      RDSLAM_LOG_WARN(
          "%s: message on %s is not a valid bot_core.image_t (wrong type or "
          "corrupt); counted as a fault",
          info_.uri.c_str(), channel_.c_str());
      warned_ = true;
    }
    return;
  }
  // Newest wins: an undelivered older image is dropped here, where it happens.
  if (has_pending_) ++counters_.skipped;
  pending_bytes_.assign(m.data, m.data + m.size);
  pending_ = m;
  pending_.data = pending_bytes_.data();
  has_pending_ = true;
  ++messages_;
}

SourceStatus LcmImageSource::read(Frame& out, int timeout_ms) {
  const uint64_t faults_before = counters_.faults;
  if (!has_pending_) {
    const int rc = lcm_.handleTimeout(timeout_ms < 0 ? 0 : timeout_ms);
    if (rc < 0) {
      ++counters_.faults;
      return SourceStatus::kFault;
    }
    if (rc == 0) {
      ++counters_.timeouts;
      return SourceStatus::kTimeout;
    }
  }
  // Drain what is already queued so the newest image is delivered.
  while (lcm_.handleTimeout(0) > 0) {
  }
  if (!has_pending_) {
    // Only invalid messages arrived (counted by the handler), or nothing for this channel.
    if (counters_.faults != faults_before) return SourceStatus::kFault;
    ++counters_.timeouts;
    return SourceStatus::kTimeout;
  }
  has_pending_ = false;
  const SourceStatus st = convert(pending_, out.image);
  if (st != SourceStatus::kOk) {
    ++counters_.faults;
    return st;
  }
  out.format = info_.format;
  out.stamp_ns = pending_.utime * 1000;
  out.arrival_mono_ns = mono_now_ns();
  out.seq = messages_ - 1;
  out.dataset_index = -1;
  ++counters_.delivered;
  return SourceStatus::kOk;
}

SourceStatus LcmImageSource::convert(const ImageMsgView& m, cv::Mat& out) {
  if (m.width != info_.width || m.height != info_.height) {
    if (!warned_) {
      RDSLAM_LOG_WARN("%s: image is %dx%d, configured %dx%d (camera.width/height); skipped",
                      info_.uri.c_str(), m.width, m.height, info_.width, info_.height);
      warned_ = true;
    }
    return SourceStatus::kFault;
  }
  switch (m.pixelformat) {
    case bot_core::image_t::PIXEL_FORMAT_GRAY:
    case bot_core::image_t::PIXEL_FORMAT_RGB:
    case bot_core::image_t::PIXEL_FORMAT_BGR:
    case bot_core::image_t::PIXEL_FORMAT_MJPEG:
      break;
    default:
      if (!warned_) {
        RDSLAM_LOG_WARN("%s: pixelformat %d is not supported (GRAY, RGB, BGR, MJPEG); skipped",
                        info_.uri.c_str(), m.pixelformat);
        warned_ = true;
      }
      return SourceStatus::kFault;
  }
  return convert_bot_core_image(m, info_.width, info_.height, info_.format, jpeg_, out);
}

SourceStatus convert_bot_core_image(const ImageMsgView& m, int width, int height,
                                    PixelFormat format, MjpegDecoder& jpeg, cv::Mat& out) {
  if (m.width != width || m.height != height) return SourceStatus::kFault;
  const bool grey_out = format == PixelFormat::kGray8;
  out.create(height, width, grey_out ? CV_8UC1 : CV_8UC3);  // no-op when sized
  void* data = const_cast<uint8_t*>(m.data);                // wrapped read-only below
  switch (m.pixelformat) {
    case bot_core::image_t::PIXEL_FORMAT_GRAY: {
      if (!fits(m.size, m.row_stride, m.width, m.height)) return SourceStatus::kFault;
      const cv::Mat in(m.height, m.width, CV_8UC1, data, static_cast<size_t>(m.row_stride));
      if (grey_out) {
        in.copyTo(out);
      } else {
        cv::cvtColor(in, out, cv::COLOR_GRAY2BGR);
      }
      return SourceStatus::kOk;
    }
    case bot_core::image_t::PIXEL_FORMAT_RGB:
    case bot_core::image_t::PIXEL_FORMAT_BGR: {
      if (!fits(m.size, m.row_stride, m.width * 3, m.height)) return SourceStatus::kFault;
      const cv::Mat in(m.height, m.width, CV_8UC3, data, static_cast<size_t>(m.row_stride));
      const bool rgb = m.pixelformat == bot_core::image_t::PIXEL_FORMAT_RGB;
      if (grey_out) {
        cv::cvtColor(in, out, rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
      } else if (rgb) {
        cv::cvtColor(in, out, cv::COLOR_RGB2BGR);
      } else {
        in.copyTo(out);
      }
      return SourceStatus::kOk;
    }
    case bot_core::image_t::PIXEL_FORMAT_MJPEG:
      return jpeg.decode(m.data, static_cast<size_t>(m.size), out) == DecodeStatus::kOk
                 ? SourceStatus::kOk
                 : SourceStatus::kFault;
    default:
      return SourceStatus::kFault;
  }
}

std::unique_ptr<FrameSource> open_lcm_image_source(const std::string& uri,
                                                   const std::string& channel,
                                                   const std::string& url, int width, int height,
                                                   PixelFormat format) {
  if (channel.empty()) throw std::runtime_error(uri + ": empty LCM channel name");
  return std::make_unique<LcmImageSource>(uri, channel, url, width, height, format);
}

}  // namespace rdslam
