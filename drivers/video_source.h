// A video file decoded with OpenCV videoio (FFmpeg backend). Frame i is stamped i / fps with
// fps from the container (or fps_override > 0): a constant-rate assumption, so a
// variable-rate file replays at its average rate. Colour videos give BGR frames, the
// frame count is the container's (a hint: the end is wherever decoding ends). Video frames
// are read sequentially: frames skipped by paced replay are grabbed but not converted.
//
// Threads: open at start-up; the reader thread calls load().
#pragma once

#include <memory>
#include <string>

#include "drivers/replay_source.h"

namespace rdslam {

// True when the extension is a common video container (avi mp4 mkv mov webm m4v mpg mpeg
// ogv), case-insensitive.
bool has_video_extension(const std::string& path);
std::unique_ptr<ReplaySource> open_video_source(const std::string& uri, const std::string& path,
                                                double fps_override, double speed);

}  // namespace rdslam
