// A folder of images (png jpg jpeg bmp pgm ppm tif tiff), replayed in natural name order
// ("img2" before "img10"). Timestamps come from the file names when every name is a time:
//   - "<seconds>.<fraction>.png" (TUM style, e.g. 1305031102.175304.png) -> exact seconds
//   - "<16 to 19 digits>.png" (EuRoC style ns, e.g. 1403715273262142976.png) -> ns
// otherwise (or when fps_override > 0) frame i is at i / fps (default 30 Hz).
//
// Threads: start-up only. Throws std::runtime_error when the folder has no images.
#pragma once

#include <memory>
#include <string>

#include "drivers/replay_source.h"

namespace rdslam {

constexpr double kDefaultImageFolderFps = 30.0;

// True when `dir` directly holds at least one image file.
bool looks_like_image_folder(const std::string& dir);
// fps_override <= 0: stamps from the names if possible, else kDefaultImageFolderFps.
std::unique_ptr<ReplaySource> open_image_folder_source(const std::string& uri,
                                                       const std::string& dir, double fps_override,
                                                       double speed);

}  // namespace rdslam
