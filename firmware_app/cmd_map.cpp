// `rdslam map`: saved maps (core/map_io.h, docs/map_format.md).
//   info    what a map file holds (header, counts), after validating it completely
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <iterator>
#include <string>

#include "core/map_io.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace rdslam {

namespace {

std::string stamp_s(int64_t ns) {
  char b[32];
  std::snprintf(b, sizeof(b), "%.3f", ns * 1e-9);
  return b;
}

int map_info(int argc, char** argv) {
  std::string path;
  ArgParser p("rdslam map info FILE",
              "Validate a saved map (size, version, checksum, every index) and print what it\n"
              "holds: camera, feature mode, keyframes, points, observations, images.");
  p.positional("FILE", &path, "map file (rdslam run/replay --save-map)");
  if (!p.parse(argc, argv)) return 0;
  const MapInfo mi = decode_map_info(read_map_file(path));
  const CameraModel& c = mi.camera;
  char when[64] = "?";
  const time_t t = static_cast<time_t>(mi.saved_unix_s);
  tm utc{};
  if (gmtime_r(&t, &utc)) std::strftime(when, sizeof(when), "%Y-%m-%d %H:%M:%S UTC", &utc);
  std::printf("%s: rdslam map, format version %u, %.1f MiB, saved %s\n", path.c_str(), mi.version,
              mi.file_bytes / 1048576.0, when);
  std::printf(
      "  camera        %s %dx%d fx %g fy %g cx %g cy %g k1 %g k2 %g p1 %g p2 %g k3 %g k4 %g\n",
      c.model.c_str(), c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.p1, c.p2, c.k3,
      c.k4);
  std::printf("  features      %s, %d-byte descriptors, %d levels, scale factor %g\n",
              mi.feature_mode.c_str(), mi.descriptor_bytes, mi.levels, mi.scale_factor);
  std::printf("  keyframes     %d (%lld keypoints; stamps %s .. %s s)\n", mi.keyframes,
              static_cast<long long>(mi.features), stamp_s(mi.first_stamp_ns).c_str(),
              stamp_s(mi.last_stamp_ns).c_str());
  std::printf("  points        %d (%lld observations, %.1f per point)\n", mi.points,
              static_cast<long long>(mi.observations),
              mi.points > 0 ? double(mi.observations) / mi.points : 0.0);
  std::printf("  images        %d keyframes with their image (PNG, %.1f MiB)\n", mi.images,
              mi.image_bytes / 1048576.0);
  return 0;
}

const Subcommand kSubs[] = {
    {"info", "validate a saved map and print what it holds", map_info},
};

}  // namespace

int cmd_map(int argc, char** argv) {
  return run_subcommand("map", "commands", kSubs, std::size(kSubs), argc, argv);
}

}  // namespace rdslam
