// libcamera source (CSI cameras on ARM boards, e.g. Raspberry Pi): `libcamera:0` (index in
// libcamera's camera list) or `libcamera:ID` (libcamera's camera id string).
//
// One stream (StreamRole::VideoRecording) in a format rdslam converts (YUV420, NV12, NV21,
// YUYV, R8 grey, MJPEG), the configured size; `buffers` requests are created once at start,
// and each completed request is recycled (Request::reuse(ReuseBuffers) + queueRequest) as
// soon as its image has been copied/converted into the caller's preallocated Frame. The
// frame timestamp is the buffer's kernel timestamp (CLOCK_MONOTONIC, FrameMetadata::timestamp).
//
// Built only when CMake finds libcamera (RDSLAM_HAVE_LIBCAMERA); this header and the
// parameters are always available so the config section exists on every build.
//
// Ownership: the source owns the CameraManager, the acquired camera, its buffers and
// requests. Threads: read() on the capture thread; libcamera's completion callback runs on
// libcamera's own thread and only moves the request into a fixed-size completed queue.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/frame_source.h"
#include "core/params.h"

namespace rdslam {

// Config section `libcamera` (systemd/rdslam.yaml).
struct LibcameraParams {
  std::string output = "grey";  // grey | bgr: what read() delivers
  int width = 0;                // 0: camera.width
  int height = 0;               // 0: camera.height
  double fps = 30.0;            // FrameDurationLimits
  int buffers = 4;              // requests / frame buffers in flight

  void visit(ParamVisitor& v) {
    v.field("output", output, {"grey", "bgr"}, "image delivered to the pipeline");
    v.field("width", width, 0, 8192, "stream width in pixels; 0 = camera.width");
    v.field("height", height, 0, 8192, "stream height in pixels; 0 = camera.height");
    v.field("fps", fps, 1.0, 1000.0, "frame rate (FrameDurationLimits)");
    v.field("buffers", buffers, 2, 16, "requests in flight");
  }
};

// Pixel layouts libcamera cameras deliver that rdslam converts (pure functions, used by the
// libcamera source and unit-tested without a camera). `planes`/`strides`: per-plane data.
enum class LibcameraLayout { kYuv420, kNv12, kNv21, kYuyv, kGrey, kMjpeg };

// Converts one frame into `out` (preallocated CV_8UC1 grey or CV_8UC3 BGR of width x height).
// YUV here is full-range or limited-range per `limited_range` (libcamera's ColorSpace).
// Returns false for short planes or a wrong `out`. No allocation.
bool convert_libcamera_frame(LibcameraLayout layout, const uint8_t* const planes[3],
                             const size_t plane_bytes[3], const size_t strides[3], int width,
                             int height, bool limited_range, cv::Mat& out);

#ifdef RDSLAM_HAVE_LIBCAMERA
// Opens `libcamera:<index or id>`; throws std::runtime_error (start-up boundary) naming the
// camera and what failed (no cameras, unknown id, unsupported format, ...).
std::unique_ptr<FrameSource> open_libcamera_source(const std::string& which,
                                                   const LibcameraParams& params, int default_width,
                                                   int default_height);
// Cameras libcamera sees, as "index: id (model)" lines. Start-up/CLI only.
std::vector<std::string> list_libcamera_cameras();
#endif

}  // namespace rdslam
