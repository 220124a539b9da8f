// Map files on the command line (issue 24): --map FILE of `rdslam run` and `rdslam replay`.
// The format and its checks are core/map_io.h's; this adds the option's name to the message.
//
// Ownership: plain values. Threads: start-up only (the main thread, before the pipeline).
#pragma once

#include <string>

#include "core/camera.h"
#include "core/features.h"
#include "core/map.h"
#include "core/map_io.h"
#include "core/params.h"

namespace rdslam {

// Config section `map` (`rdslam run`): where and when the daemon saves its map.
struct MapFileParams {
  std::string save_path;         // "" = never saved (--save-map FILE sets it)
  bool save_on_shutdown = true;  // at the end of the run (source ended, SIGINT/SIGTERM)
  double save_period_s = 0.0;    // > 0: also every this many seconds while running
  int keep = 1;                  // versions kept: FILE, FILE.1 .. FILE.(keep-1)
  int writer_nice = 19;          // nice of the thread that encodes and writes saves while running
  void visit(ParamVisitor& v);
};

// Reads, validates and decodes `path` and checks that it was made with `camera` and
// `features`' mode. Throws MapFormatError "--map PATH: <why>" (the map is not used then).
Map load_prior_map(const std::string& path, const CameraModel& camera,
                   const FeatureParams& features, MapInfo* info = nullptr);

}  // namespace rdslam
