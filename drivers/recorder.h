// Records frames as a TUM RGB-D style folder that `tum:DIR` (or a bare DIR) replays
// bit-identically:
//   DIR/rgb/<stamp>.png   lossless PNG of the frame as delivered (grey or BGR)
//   DIR/rgb.txt           "<stamp> rgb/<stamp>.png", stamp = Frame::stamp_ns as seconds with
//                         exactly 9 decimals (core/timestamp.h), so it reads back exactly
//   DIR/camera.yaml       the intrinsics in effect while recording (FrameSource::camera())
// Crash safety: each PNG is written to a temporary name and renamed into place BEFORE its
// rgb.txt line is appended (one write() on an O_APPEND descriptor), so rgb.txt never names
// a missing or partial image, whenever the process stops.
//
// Ownership: owns the folder's file descriptors. Threads: one thread (the recording loop).
// Constructor throws std::runtime_error (start-up boundary); write() returns false on I/O
// failure and counts it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/frame_source.h"

namespace rdslam {

class TumRecorder {
 public:
  // Refuses to overwrite: `dir` must not exist, or be an empty folder. `source_uri` is noted
  // in rgb.txt's header.
  TumRecorder(const std::string& dir, const std::string& source_uri,
              const std::optional<CameraModel>& camera);
  ~TumRecorder();
  TumRecorder(const TumRecorder&) = delete;
  TumRecorder& operator=(const TumRecorder&) = delete;

  // Appends one frame. Returns false (and counts it) when the image cannot be written.
  bool write(const Frame& frame);
  // Flushes rgb.txt to disk (fsync) and closes it; idempotent, also run by the destructor.
  void close();

  uint64_t written() const { return written_; }
  uint64_t failures() const { return failures_; }
  uint64_t bytes() const { return bytes_; }

 private:
  std::string dir_;
  int list_fd_ = -1;
  std::vector<uint8_t> png_;     // encode buffer, reused
  std::vector<int> png_params_;  // fixed at construction
  int64_t last_stamp_ns_ = 0;
  uint64_t written_ = 0;
  uint64_t failures_ = 0;
  uint64_t bytes_ = 0;
};

}  // namespace rdslam
