#include "drivers/dataset_tum.h"

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "core/timestamp.h"

namespace rdslam {

namespace fs = std::filesystem;

bool looks_like_tum(const std::string& dir) {
  return fs::is_regular_file(fs::path(dir) / "rgb.txt");
}

TumDataset read_tum_dataset(const std::string& dir) {
  const fs::path root(dir);
  const std::string list = (root / "rgb.txt").string();
  std::ifstream in(list);
  if (!in) throw std::runtime_error(list + ": cannot open (not a TUM RGB-D folder?)");
  TumDataset ds;
  std::string line;
  for (size_t n = 1; std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line[start] == '#') continue;
    const size_t sep = line.find_first_of(" \t", start);
    const size_t name_start =
        sep == std::string::npos ? std::string::npos : line.find_first_not_of(" \t", sep);
    if (name_start == std::string::npos) {
      throw std::runtime_error(list + ":" + std::to_string(n) + ": expected 'timestamp filename'");
    }
    size_t name_end = line.find_first_of(" \t", name_start);
    if (name_end != std::string::npos &&
        line.find_first_not_of(" \t", name_end) != std::string::npos) {
      throw std::runtime_error(list + ":" + std::to_string(n) +
                               ": expected 'timestamp filename', found more fields");
    }
    if (name_end == std::string::npos) name_end = line.size();
    ImageFileSequence::Item item;
    const std::string stamp = line.substr(start, sep - start);
    if (!parse_seconds_ns(stamp, item.stamp_ns)) {
      throw std::runtime_error(list + ":" + std::to_string(n) + ": timestamp '" + stamp +
                               "' is not a time in seconds");
    }
    const fs::path file(line.substr(name_start, name_end - name_start));
    item.path = (file.is_absolute() ? file : root / file).string();
    ds.frames.push_back(std::move(item));
  }
  if (ds.frames.empty()) throw std::runtime_error(list + ": lists no images");
  const fs::path gt = root / "groundtruth.txt";
  if (fs::is_regular_file(gt))
    ds.ground_truth = read_trajectory(gt.string(), TrajectoryFormat::kTum);
  return ds;
}

std::unique_ptr<ReplaySource> open_tum_source(const std::string& uri, const std::string& dir,
                                              double speed) {
  TumDataset ds = read_tum_dataset(dir);
  return make_image_replay(uri, "tum", std::move(ds.frames), std::nullopt,
                           std::move(ds.ground_truth), speed);
}

}  // namespace rdslam
