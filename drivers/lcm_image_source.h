// `lcm:CHANNEL[?format=gray|bgr]`: frames from libbot2 bot_core.image_t messages
// (lcmtypes/bot_core_image_t.lcm), so a robot log replayed with lcm-logplayer drives rdslam
// exactly as the live camera did. Pixel formats: GRAY, RGB, BGR (any row_stride) and MJPEG
// (decoded with libjpeg-turbo, drivers/mjpeg_decoder.h); others are counted as faults.
//
// Semantics (as a live camera): read() waits up to timeout_ms for a message, then drains
// everything already queued and delivers the NEWEST image; the older ones are counted in
// SourceCounters::skipped and show as gaps in Frame::seq (message count). Frame::stamp_ns =
// utime * 1000 (the capture time the publisher wrote); arrival_mono_ns = CLOCK_MONOTONIC
// when read() took the message.
// The frame size is fixed at open (the configured camera's width x height) so the caller can
// preallocate; messages of another size, bad fingerprints (another type on the channel) and
// corrupt JPEGs are counted faults, never crashes. The message is parsed in place from
// LCM's receive buffer (no generated decode(), whose std::vector resize would allocate and
// trust the message's size field): the latest payload is copied into one reused buffer.
//
// Ownership: owns its lcm::LCM instance (one UDP socket). Threads: one reader thread calls
// read(); LCM's handler runs inside read() on that thread.
#pragma once

#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>
#include <vector>

#include "core/frame_source.h"
#include "drivers/mjpeg_decoder.h"

namespace rdslam {

// Parsed view of one bot_core.image_t (pointers into the encoded message).
struct ImageMsgView {
  int64_t utime = 0;
  int32_t width = 0, height = 0, row_stride = 0, pixelformat = 0;
  const uint8_t* data = nullptr;
  int32_t size = 0;
};
// Checks fingerprint and bounds of an encoded bot_core.image_t; false when malformed.
bool parse_bot_core_image(const uint8_t* buf, size_t len, ImageMsgView& out);
// Converts a parsed message into `out`, a width x height grey (kGray8) or BGR (kBgr8) frame
// (allocated when it is not one). kFault for another size, a pixel format other than GRAY,
// RGB, BGR, MJPEG, a payload too short for its row stride, or a corrupt JPEG.
SourceStatus convert_bot_core_image(const ImageMsgView& m, int width, int height,
                                    PixelFormat format, MjpegDecoder& jpeg, cv::Mat& out);

class LcmImageSource : public FrameSource {
 public:
  // Throws std::runtime_error when LCM cannot be initialised with `url`.
  LcmImageSource(std::string uri, std::string channel, const std::string& url, int width,
                 int height, PixelFormat format);
  SourceStatus read(Frame& out, int timeout_ms) override;
  const SourceInfo& info() const override { return info_; }
  SourceCounters counters() const override { return counters_; }

 private:
  // C-API handler (lcm_subscribe): LCM's C++ template wrapper casts through void* in a way
  // UBSan's vptr check rejects; the C callback with `this` as user data is exact.
  static void on_message_c(const lcm_recv_buf_t* rbuf, const char* channel, void* self);
  void on_message(const uint8_t* data, size_t size);
  SourceStatus convert(const ImageMsgView& m, cv::Mat& out);

  SourceInfo info_;
  std::string channel_;
  lcm::LCM lcm_;
  SourceCounters counters_;
  MjpegDecoder jpeg_;
  // The newest valid message not yet delivered (payload bytes copied, header fields kept).
  std::vector<uint8_t> pending_bytes_;
  ImageMsgView pending_;
  bool has_pending_ = false;
  uint64_t messages_ = 0;  // valid messages seen; Frame::seq = index of the delivered one
  bool warned_ = false;
};

// Factory entry (source_factory.cpp): frames are `width` x `height` (the configured camera).
std::unique_ptr<FrameSource> open_lcm_image_source(const std::string& uri,
                                                   const std::string& channel,
                                                   const std::string& url, int width, int height,
                                                   PixelFormat format);

}  // namespace rdslam
