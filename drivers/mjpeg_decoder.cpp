#include "drivers/mjpeg_decoder.h"

#include <turbojpeg.h>

#include <cstdio>
#include <stdexcept>

namespace rdslam {

const char* to_string(DecodeStatus s) {
  switch (s) {
    case DecodeStatus::kOk:
      return "ok";
    case DecodeStatus::kCorrupt:
      return "corrupt";
    case DecodeStatus::kSizeMismatch:
      return "size-mismatch";
    case DecodeStatus::kBadOutput:
      return "bad-output";
  }
  return "unknown";
}

MjpegDecoder::MjpegDecoder(bool strict) : strict_(strict) {
  handle_ = tjInitDecompress();
  // Start-up boundary: without a decoder the MJPEG path cannot run at all.
  if (!handle_) throw std::runtime_error("mjpeg: tjInitDecompress failed");
}

MjpegDecoder::~MjpegDecoder() {
  if (handle_) tjDestroy(static_cast<tjhandle>(handle_));
}

bool MjpegDecoder::peek_size(const uint8_t* data, size_t bytes, int& width, int& height) {
  // A JPEG starts with SOI (FF D8); checking it first keeps garbage out of libjpeg.
  if (!data || bytes < 4 || data[0] != 0xFF || data[1] != 0xD8) {
    last_error_ = "no JPEG SOI marker";
    return false;
  }
  int subsamp = 0;
  int colorspace = 0;
  if (!handle_) {
    last_error_ = "no TurboJPEG handle (re-creation after a corrupt header failed)";
    return false;
  }
  if (tjDecompressHeader3(static_cast<tjhandle>(handle_), data, static_cast<unsigned long>(bytes),
                          &width, &height, &subsamp, &colorspace) != 0) {
    // Copy the message before the handle goes away.
    std::snprintf(error_buf_, sizeof(error_buf_), "%s",
                  tjGetErrorStr2(static_cast<tjhandle>(handle_)));
    last_error_ = error_buf_;
    // libjpeg-turbo 2.1: a header that fails mid-marker leaves the decompressor inside that
    // marker, and every later header read fails too ("Bogus Huffman table definition" for
    // good frames; found by TruncatedFrameIsCorruptAndDecoderRecovers). A fresh handle is
    // the only public way to reset it. This allocates, but only on the fault path.
    tjDestroy(static_cast<tjhandle>(handle_));
    handle_ = tjInitDecompress();
    return false;
  }
  return true;
}

DecodeStatus MjpegDecoder::decode(const uint8_t* data, size_t bytes, cv::Mat& out) {
  if (out.empty() || (out.type() != CV_8UC1 && out.type() != CV_8UC3)) {
    last_error_ = "output buffer not preallocated as CV_8UC1/CV_8UC3";
    return DecodeStatus::kBadOutput;
  }
  int width = 0;
  int height = 0;
  if (!peek_size(data, bytes, width, height)) return DecodeStatus::kCorrupt;
  if (width != out.cols || height != out.rows) {
    last_error_ = "JPEG size differs from the negotiated size";
    return DecodeStatus::kSizeMismatch;
  }
  const int pixel_format = out.type() == CV_8UC1 ? TJPF_GRAY : TJPF_BGR;
  const int flags = strict_ ? TJFLAG_STOPONWARNING : 0;
  tjhandle h = static_cast<tjhandle>(handle_);
  if (tjDecompress2(h, data, static_cast<unsigned long>(bytes), out.data, width,
                    static_cast<int>(out.step[0]), height, pixel_format, flags) != 0) {
    last_error_ = tjGetErrorStr2(h);
    // Without strict mode a warning still produced a full image; accept it.
    if (!strict_ && tjGetErrorCode(h) == TJERR_WARNING) return DecodeStatus::kOk;
    return DecodeStatus::kCorrupt;
  }
  last_error_ = "";
  return DecodeStatus::kOk;
}

}  // namespace rdslam
