#include "firmware_app/map_files.h"

namespace rdslam {

void MapFileParams::visit(ParamVisitor& v) {
  v.field("save_path", save_path, {},
          "map file the daemon saves to (empty: none); `rdslam run --save-map FILE` sets it");
  v.field("save_on_shutdown", save_on_shutdown, "save the map when the run ends");
  v.field("save_period_s", save_period_s, 0.0, 86400.0,
          "also save every this many seconds while running (0: off)");
  v.field("keep", keep, 1, 100, "map versions kept: FILE, FILE.1 .. FILE.(keep-1)");
  v.field("writer_nice", writer_nice, 0, 19,
          "nice value of the thread that encodes and writes the saves made while running (on "
          "the mapper's cores)");
}

Map load_prior_map(const std::string& path, const CameraModel& camera,
                   const FeatureParams& features, MapInfo* info) {
  try {
    const std::vector<uint8_t> bytes = read_map_file(path);
    MapInfo mi;
    Map map = decode_map(bytes, &mi);
    const std::string why = check_map_compatible(mi, camera, features);
    if (!why.empty()) throw MapFormatError(why);
    if (info) *info = mi;
    return map;
  } catch (const MapFormatError& e) {
    std::string m = e.what();
    if (m.rfind("map: ", 0) == 0) m = m.substr(5);
    throw MapFormatError("--map " + path + ": " + m);
  }
}

}  // namespace rdslam
