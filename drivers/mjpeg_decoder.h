// MJPEG (one JPEG per frame, as UVC cameras send it) decoding with libjpeg-turbo's
// TurboJPEG API straight into a caller-preallocated cv::Mat (BGR or grey): no per-frame
// allocation in rdslam's code. (libjpeg's own per-image work arrays come from its pool
// allocator inside tjDecompress2; that is internal to the library and bounded.)
//
// Corrupt input -- a truncated USB transfer, garbage, a frame of the wrong size -- is
// reported as a status, never thrown: the caller counts it and skips the frame.
//
// Ownership: owns one TurboJPEG handle. Threads: one thread at a time (the capture thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

namespace rdslam {

enum class DecodeStatus : uint8_t {
  kOk = 0,
  kCorrupt = 1,       // not a JPEG, truncated, or libjpeg reported an error/warning
  kSizeMismatch = 2,  // decodable, but not the size `out` was allocated for
  kBadOutput = 3,     // `out` is empty or neither CV_8UC1 nor CV_8UC3
};

const char* to_string(DecodeStatus s);

class MjpegDecoder {
 public:
  // strict = true: a libjpeg warning (e.g. "Premature end of JPEG file", which libjpeg
  // otherwise papers over by filling the missing rows with grey) rejects the frame. Grey
  // filler rows would give the tracker false edges, so strict is the default.
  explicit MjpegDecoder(bool strict = true);
  ~MjpegDecoder();
  MjpegDecoder(const MjpegDecoder&) = delete;
  MjpegDecoder& operator=(const MjpegDecoder&) = delete;

  // Reads only the header: image size. Returns false when the data is not a JPEG.
  bool peek_size(const uint8_t* data, size_t bytes, int& width, int& height);
  // Decodes into `out` (must be preallocated CV_8UC3 BGR or CV_8UC1 grey, exact size).
  DecodeStatus decode(const uint8_t* data, size_t bytes, cv::Mat& out);
  // Last libjpeg message (for a debug log line); valid until the next call.
  const char* last_error() const { return last_error_; }

 private:
  void* handle_ = nullptr;  // tjhandle
  bool strict_ = true;
  const char* last_error_ = "";
  char error_buf_[200] = {};
};

}  // namespace rdslam
