// libFuzzer target: the LCM messages rdslam receives, bot_core.image_t on an `lcm:CHANNEL`
// source (drivers/lcm_image_source.h): the bounds-checked parse of the encoded message as it
// arrives in LCM's receive buffer, then the conversion into 16 x 12 grey and BGR frames
// (pixel copy with the message's row stride, colour conversion, or the MJPEG decoder). A bad
// message must be a rejected parse or a kFault; a crash or a sanitizer report is a bug.
// The input is the whole encoded message (fingerprint first: the seeds carry the real one).
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>

#include "drivers/lcm_image_source.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static rdslam::MjpegDecoder jpeg(true);
  static cv::Mat grey(12, 16, CV_8UC1), bgr(12, 16, CV_8UC3);
  rdslam::ImageMsgView view;
  if (!rdslam::parse_bot_core_image(data, size, view)) return 0;
  (void)rdslam::convert_bot_core_image(view, 16, 12, rdslam::PixelFormat::kGray8, jpeg, grey);
  (void)rdslam::convert_bot_core_image(view, 16, 12, rdslam::PixelFormat::kBgr8, jpeg, bgr);
  return 0;
}
