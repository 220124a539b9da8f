// YUYV 4:2:2 (V4L2_PIX_FMT_YUYV, byte order Y0 U Y1 V) to BGR or grey, written into a
// caller-preallocated cv::Mat. USB (UVC) cameras send YUYV in BT.601 limited range
// (Y 16..235, Cb/Cr 16..240); the conversion expands it to full range 0..255 so a YUYV
// camera and an MJPEG camera (JFIF, full range) give the tracker the same intensities.
//
// Ownership: pure functions over caller buffers; nothing is allocated. Threads: any thread;
// the lookup tables are built once, thread-safely, on first use.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>

namespace rdslam {

// Converts a width x height YUYV image (`stride` bytes per source row, >= 2*width) into
// `out`, which must already be CV_8UC3 (BGR) or CV_8UC1 (grey) of size height x width.
// Returns false (and leaves `out` untouched) when the sizes, type or width parity do not
// fit or when `bytes` is too small for the image: a short USB frame is a fault, not a crash.
bool yuyv_to_image(const uint8_t* src, size_t bytes, int width, int height, size_t stride,
                   cv::Mat& out);

}  // namespace rdslam
