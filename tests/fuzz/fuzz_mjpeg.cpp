// libFuzzer target: MJPEG frames as a USB camera (V4L2) or a bot_core.image_t message hands
// them over (drivers/mjpeg_decoder.h): header peek, then strict and lenient decoding into
// preallocated grey and BGR frames of the peeked size (when small) and of a fixed 32 x 24
// size. Every outcome must be a DecodeStatus; a crash or a sanitizer report is a bug.
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>

#include "drivers/mjpeg_decoder.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static rdslam::MjpegDecoder strict(true), lenient(false);
  static cv::Mat grey(24, 32, CV_8UC1), bgr(24, 32, CV_8UC3);
  int w = 0, h = 0;
  if (strict.peek_size(data, size, w, h) && w > 0 && h > 0 && int64_t{w} * h <= 256 * 256) {
    cv::Mat exact(h, w, CV_8UC1);
    (void)strict.decode(data, size, exact);
    cv::Mat exact_bgr(h, w, CV_8UC3);
    (void)lenient.decode(data, size, exact_bgr);
  }
  (void)strict.decode(data, size, grey);
  (void)lenient.decode(data, size, bgr);
  cv::Mat empty;
  (void)strict.decode(data, size, empty);
  return 0;
}
