// Debug video and images of `rdslam replay --debug-video OUT.mp4 --debug-images DIR`: per
// frame, what the system decided, drawn like the RDSLAM paper's Figures 4, 9 and 10:
//   - the camera image with the tracked features split into inliers (green dots) and the
//     matches rejected by the robust estimator (orange crosses) or by the eq. (1) refinement
//     (magenta crosses); while LOST the remaining matches are yellow rings;
//   - the valid map points of the tracker's matching index projected with the frame's pose
//     (cyan), the points invalidated by map updating within the last `recent_frames` frames
//     projected with the same pose (red);
//   - a header: frame number, tracking state, inliers and outliers, map points, keyframes,
//     points invalidated so far;
//   - a side panel: top view (world x right, z up) of the map points, recently invalidated
//     points, keyframe centres, the camera track and the current camera.
//
// DebugRenderer draws (pure, testable). DebugVideoWriter is the tracker's DebugFrameSink
// (core/debug_frame.h): the tracker thread only queues the record (a bounded queue; in
// lossless replay it waits for room, otherwise the record is dropped and counted), a writer
// thread of its own draws and encodes (OpenCV videoio, FFmpeg backend, 'avc1' H.264 if
// available, else 'mp4v') and writes the PNGs. Output paths are checked, and the video file is
// opened, in the constructor, so a bad path is an error at start (UsageError, exit 2).
//
// Ownership: the writer owns its thread, queue, renderer and cv::VideoWriter. Threads:
// construct, finish() and destroy on the supervising thread; on_debug_frame() on the tracker
// thread only (one producer).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "core/camera.h"
#include "core/debug_frame.h"

namespace rdslam {

// BGR colours of the drawing (also the legend's).
struct DebugColours {
  static cv::Scalar inlier() { return {0, 220, 0}; }
  static cv::Scalar rejected_robust() { return {0, 140, 255}; }  // orange
  static cv::Scalar rejected_refine() { return {255, 0, 255}; }  // magenta
  static cv::Scalar unsupported() { return {0, 230, 255}; }      // yellow
  static cv::Scalar map_point() { return {255, 255, 0}; }        // cyan
  static cv::Scalar invalidated() { return {0, 0, 255}; }        // red
  static cv::Scalar keyframe() { return {255, 255, 255}; }
  static cv::Scalar track() { return {0, 200, 255}; }
};

class DebugRenderer {
 public:
  // `recent_frames`: an invalidated point stays red this many frames after the first frame
  // whose snapshot lists it.
  DebugRenderer(const CameraModel& camera, int recent_frames);

  // Canvas layout: header on top, the camera image below it at image_origin(), the top-view
  // panel to its right. Width and height are even (video encoders need it).
  cv::Size canvas_size() const { return canvas_; }
  cv::Point image_origin() const { return {0, header_h_}; }
  cv::Rect panel_rect() const { return {camera_.width, header_h_, panel_, panel_}; }

  // Every frame, in order (also those not drawn): camera track, invalidation ages.
  void observe(const DebugFrame& d);
  // Forgets the camera track (the top view's; it grows by one position per tracked frame).
  // For a long-running user that does not draw the top view (the live viewer).
  void clear_track() { track_.clear(); }
  // Draws `d` (after observe(d)) into `canvas` (reallocated to canvas_size(), CV_8UC3).
  void render(const DebugFrame& d, cv::Mat& canvas);

  // Frame number shown in the header: the dataset index when the source has one, else the
  // count of frames observed so far (0-based).
  int64_t frame_number(const DebugFrame& d) const;
  // Recently invalidated points of the last observed frame (for the header and tests).
  int recent_invalid() const { return recent_count_; }

 private:
  bool recent(int64_t id) const;
  void project(const Pose& T,
               const std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>& p,
               std::vector<cv::Point2f>& uv, std::vector<uint8_t>& ok) const;
  void draw_panel(const DebugFrame& d, cv::Mat panel);
  void update_bounds(const DebugFrame& d);

  CameraModel camera_;
  int recent_frames_;
  int header_h_ = 48, panel_ = 0;
  cv::Size canvas_;
  int64_t observed_ = 0;
  uint32_t epoch_ = 0;
  std::unordered_map<int64_t, int64_t> first_seen_;  // invalid point id -> first frame listed
  int recent_count_ = 0;
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> track_;
  bool have_bounds_ = false;
  double min_x_ = 0, max_x_ = 0, min_z_ = 0, max_z_ = 0;
  // Scratch.
  std::vector<cv::Point2f> uv_;
  std::vector<uint8_t> ok_;
  std::vector<double> xs_, zs_;
  cv::Mat bgr_;
};

struct DebugVideoOptions {
  std::string video_path;  // empty: no video
  std::string images_dir;  // empty: no PNGs (created if missing)
  int every = 1;           // draw every N-th frame (the track panel still sees every frame)
  int recent_frames = 30;  // invalidated points stay red this many frames
  double fps = 30.0;       // video frame rate (the source's nominal rate)
  bool lossless = true;    // queue full: wait (lossless replay) or drop the record
  int queue_frames = 8;    // records queued between tracker and writer
};

struct DebugVideoStats {
  int64_t received = 0;  // records the tracker handed over
  int64_t dropped = 0;   // records dropped because the queue was full (not lossless)
  int64_t drawn = 0;     // frames drawn
  int64_t video_frames = 0, images = 0;
  std::string codec;  // FOURCC used for the video
  std::string error;  // first write error, empty if none
};

// Checks that the outputs can be written (the video's directory exists, the images
// directory can be created and written) without opening the video; throws UsageError naming
// the path. Cheap: call before opening the source.
void check_debug_output_paths(const DebugVideoOptions& options);

class DebugVideoWriter final : public DebugFrameSink {
 public:
  // Opens the video (and checks the paths); throws UsageError naming the path on failure.
  DebugVideoWriter(const DebugVideoOptions& options, const CameraModel& camera);
  ~DebugVideoWriter() override;
  DebugVideoWriter(const DebugVideoWriter&) = delete;
  DebugVideoWriter& operator=(const DebugVideoWriter&) = delete;

  // Tracker thread.
  void on_debug_frame(DebugFrame&& frame) override;
  // Supervising thread, after the pipeline has joined: draws what is queued, closes the
  // video, joins the writer thread. Idempotent.
  DebugVideoStats finish();

 private:
  void worker();
  void write(const DebugFrame& d);

  DebugVideoOptions options_;
  DebugRenderer renderer_;
  cv::VideoWriter video_;
  std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  std::deque<std::unique_ptr<DebugFrame>> queue_;
  bool closing_ = false;
  bool finished_ = false;
  DebugVideoStats stats_;  // writer thread (received/dropped: tracker thread under mutex_)
  int64_t observed_ = 0;   // writer thread
  cv::Mat canvas_;
  std::thread thread_;
};

}  // namespace rdslam
