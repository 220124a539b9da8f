// TUM RGB-D dataset folders (Sturm et al., IROS 2012) and rdslam recordings:
//   DIR/rgb.txt          "timestamp filename" per line, timestamp in seconds, '#' comments
//   DIR/rgb/*.png        the images the list names (paths relative to DIR)
//   DIR/groundtruth.txt  optional, TUM trajectory "t tx ty tz qx qy qz qw" of the colour
//                        camera's optical centre in the mocap world: T_world_cam as is.
// TUM sequences ship no calibration file: the intrinsics come from a camera.yaml beside the
// data (source_factory), which makes a TUM folder with camera.yaml a complete dataset.
// Timestamps are parsed exactly (core/timestamp.h), so a recording replays bit-identically.
//
// Threads: start-up only. Throws std::runtime_error naming file and line on bad input.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/replay_source.h"

namespace rdslam {

struct TumDataset {
  std::vector<ImageFileSequence::Item> frames;  // in file order, paths made absolute
  std::optional<Trajectory> ground_truth;
};

// True when `dir` has an rgb.txt.
bool looks_like_tum(const std::string& dir);
TumDataset read_tum_dataset(const std::string& dir);
std::unique_ptr<ReplaySource> open_tum_source(const std::string& uri, const std::string& dir,
                                              double speed);

}  // namespace rdslam
