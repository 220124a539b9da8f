// libFuzzer target: the LCM messages rdslam receives. Each input is offered to both receivers,
// as any bytes may arrive on a subscribed channel:
// - bot_core.image_t on an `lcm:CHANNEL` source (drivers/lcm_image_source.h): the
//   bounds-checked parse of the encoded message as it arrives in LCM's receive buffer, then the
//   conversion into 16 x 12 grey and BGR frames (pixel copy with the message's row stride,
//   colour conversion, or the MJPEG decoder). A bad message must be a rejected parse or a
//   kFault.
// - rdslam.command_t on lcm.command_channel (firmware_app/lcm_commands.h,
//   apply_command_message): a bad message must be kMalformed or kRejected and leave the link
//   untouched; an accepted one changes only the field its code names.
// A crash, a sanitizer report or a broken invariant (abort) is a bug. The input is the whole
// encoded message (fingerprint first: the seeds carry the real ones).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <opencv2/core.hpp>

#include "drivers/lcm_image_source.h"
#include "firmware_app/lcm_commands.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static rdslam::MjpegDecoder jpeg(true);
  static cv::Mat grey(12, 16, CV_8UC1), bgr(12, 16, CV_8UC3);
  static rdslam::SlamLink link(2);
  for (bool can_save : {false, true}) {
    const uint64_t resets = link.reset_requests.load(), saves = link.save_requests.load();
    int8_t code = 0;
    const auto v =
        rdslam::apply_command_message(data, static_cast<uint32_t>(size), link, can_save, &code);
    const bool changed = link.reset_requests.load() != resets || link.save_requests.load() != saves;
    if (v != rdslam::CommandVerdict::kAccepted && changed) std::abort();
    if (v == rdslam::CommandVerdict::kAccepted && code != 1 && code != 2 && code != 3 && code != 4)
      std::abort();
  }
  rdslam::ImageMsgView view;
  if (!rdslam::parse_bot_core_image(data, size, view)) return 0;
  (void)rdslam::convert_bot_core_image(view, 16, 12, rdslam::PixelFormat::kGray8, jpeg, grey);
  (void)rdslam::convert_bot_core_image(view, 16, 12, rdslam::PixelFormat::kBgr8, jpeg, bgr);
  return 0;
}
