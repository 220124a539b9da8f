// Recorded sequences (datasets, image folders, video files, recordings) and the one
// FrameSource that replays them, with the replay pacing.
//
// Pacing (SourceOptions::speed):
//  - speed 0: as fast as the reader reads; every frame is delivered, in order. This is the
//    default of `rdslam replay` and gives reproducible runs.
//  - speed X > 0 (hardware-in-the-loop): frame i is due at
//        due_i = t0 + (stamp_i - stamp_0) / X
//    (t0 = CLOCK_MONOTONIC when the first frame is decoded, during the first read()),
//    whether or not anyone reads. read() sleeps on an absolute CLOCK_MONOTONIC deadline
//    (clock_nanosleep TIMER_ABSTIME: no drift accumulates) until the next frame is due.
//    A reader that comes late gets the NEWEST due frame; the frames passed over are counted
//    in SourceCounters::skipped, exactly as a live camera whose driver overwrites its
//    buffers. The source reports info().live = true, so the pipeline applies its live
//    policy (the capture ring's "newest frame wins"); most drops then happen in that ring and
//    `skipped` only grows when the capture thread itself falls behind (e.g. PNG decoding
//    slower than the frame rate). The next frame is decoded BEFORE sleeping to its deadline,
//    so decode time does not add to the schedule error (bench_replay_pacing measures it).
//    Frame::arrival_mono_ns is the due time: the moment a live camera would have delivered
//    the frame, so latency figures include any time the frame waited for the reader.
//
// Ownership: ReplaySource owns its RecordedSequence and a staging image (paced mode).
// Threads: one reader thread calls read(); everything else is immutable after open.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/frame_source.h"

namespace rdslam {

// CLOCK_MONOTONIC, behind a seam so pacing tests can run on a simulated clock.
class MonoClock {
 public:
  virtual ~MonoClock() = default;
  virtual int64_t now_ns() = 0;
  // Sleeps until CLOCK_MONOTONIC >= deadline_ns (absolute; returns at once when past).
  virtual void sleep_until_ns(int64_t deadline_ns) = 0;
};
MonoClock& system_mono_clock();

// A recorded sequence of frames with known timestamps.
class RecordedSequence {
 public:
  virtual ~RecordedSequence() = default;
  // Stamp of frame `index` without decoding it; false when there is no such frame (for
  // sequences of unknown length, e.g. some videos, true until load() reports the end).
  virtual bool stamp(int64_t index, int64_t& stamp_ns) const = 0;
  // Decodes frame `index` into `image` (reused when it has the right size and type; the
  // sequence's pixel format and size are fixed at open). Indices strictly increase between
  // calls but may jump (skipped frames are never decoded when the format allows it).
  // Returns kOk, kEndOfStream (no such frame) or kFault (unreadable or wrong-size frame).
  virtual SourceStatus load(int64_t index, cv::Mat& image) = 0;
};

class ReplaySource : public FrameSource {
 public:
  // `info` must carry width, height, format and frame_count; `live` is set from `speed`.
  ReplaySource(std::unique_ptr<RecordedSequence> sequence, SourceInfo info,
               std::optional<CameraModel> camera, std::optional<Trajectory> ground_truth,
               double speed, MonoClock& clock = system_mono_clock());

  SourceStatus read(Frame& out, int timeout_ms) override;
  const SourceInfo& info() const override { return info_; }
  std::optional<CameraModel> camera() const override { return camera_; }
  std::optional<Trajectory> ground_truth() const override { return ground_truth_; }
  SourceCounters counters() const override { return counters_; }

 private:
  SourceStatus read_unpaced(Frame& out);
  SourceStatus read_paced(Frame& out, int timeout_ms);
  int64_t due_ns(int64_t stamp_ns) const;
  void fill(Frame& out, int64_t index, int64_t stamp_ns, int64_t arrival_ns);

  std::unique_ptr<RecordedSequence> seq_;
  SourceInfo info_;
  std::optional<CameraModel> camera_;
  std::optional<Trajectory> ground_truth_;
  double speed_;
  MonoClock& clock_;
  SourceCounters counters_;
  int64_t next_ = 0;  // index of the next frame to deliver
  bool eos_ = false;
  // Paced mode.
  bool started_ = false;
  int64_t t0_ns_ = 0;      // CLOCK_MONOTONIC when the first frame was ready
  int64_t stamp0_ns_ = 0;  // stamp of the first delivered frame
  cv::Mat staging_;        // frame `next_`, decoded ahead of its deadline
  bool staged_ = false;
  int64_t staged_stamp_ns_ = 0;
};

// ---- helpers shared by the dataset readers (start-up unless stated) ----

// Decodes image files into a fixed pixel format and size, reusing its buffers (file bytes
// and decode scratch): after the first frame no buffer of ours grows. The codec libraries'
// internal work memory is theirs. Called from the reader thread only.
class ImageFileDecoder {
 public:
  // Reads `path` and converts it to `format` into `out`. kFault when unreadable,
  // undecodable, not 8-bit, or not `width` x `height` (when both > 0).
  SourceStatus decode(const std::string& path, PixelFormat format, int width, int height,
                      cv::Mat& out);

 private:
  std::vector<uint8_t> bytes_;
  cv::Mat scratch_;
};

// Opens `path` and reports its size and native format (grey for 1-channel images, BGR
// otherwise). Throws std::runtime_error when it is not a readable 8-bit image.
void probe_image(const std::string& path, int& width, int& height, PixelFormat& format);

// A RecordedSequence over image files with known stamps (TUM, EuRoC, KITTI, folders).
// load() asks the kernel to read the next kReadAhead files ahead (posix_fadvise WILLNEED,
// asynchronous): a long sequence does not stay in the page cache on a busy machine, and a
// paced replay's capture thread must not wait for the disk (docs/benchmarks.md).
class ImageFileSequence : public RecordedSequence {
 public:
  struct Item {
    int64_t stamp_ns;
    std::string path;
  };
  ImageFileSequence(std::vector<Item> items, PixelFormat format, int width, int height)
      : items_(std::move(items)), format_(format), width_(width), height_(height) {}
  bool stamp(int64_t index, int64_t& stamp_ns) const override;
  SourceStatus load(int64_t index, cv::Mat& image) override;
  static constexpr int64_t kReadAhead = 16;  // frames (about 0.5 s at 30 fps)

 private:
  std::vector<Item> items_;
  int64_t advised_ = -1;  // highest index whose file was handed to the kernel's read-ahead
  PixelFormat format_;
  int width_, height_;
  ImageFileDecoder decoder_;
};

// Builds the ReplaySource for an image-file sequence: probes the first frame for size and
// format, fills SourceInfo (nominal_fps from the median stamp step). Throws when empty.
std::unique_ptr<ReplaySource> make_image_replay(const std::string& uri, const std::string& kind,
                                                std::vector<ImageFileSequence::Item> items,
                                                std::optional<CameraModel> camera,
                                                std::optional<Trajectory> ground_truth,
                                                double speed);

// Reads a `camera.yaml` (keys width, height, fx, fy, cx, cy, optional k1 k2 p1 p2 k3 k4 in
// OpenCV order, optional model: pinhole-radtan|pinhole-equidistant). Throws
// std::runtime_error naming the file and key on unknown keys, bad values or failed
// CameraModel::validate().
CameraModel read_camera_yaml(const std::string& path);
// Writes the keys read_camera_yaml reads.
void write_camera_yaml(const std::string& path, const CameraModel& camera);

// True when `name` ends with a known image extension (png jpg jpeg bmp pgm ppm tif tiff),
// case-insensitive.
bool has_image_extension(const std::string& name);
// Compares names so that embedded numbers sort by value ("img2" < "img10"); for
// zero-padded names this is plain lexicographic order.
bool natural_less(const std::string& a, const std::string& b);

}  // namespace rdslam
