#include "drivers/image_folder_source.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "core/timestamp.h"

namespace rdslam {

namespace fs = std::filesystem;

namespace {

std::vector<std::string> image_names(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file() && has_image_extension(e.path().filename().string())) {
      names.push_back(e.path().filename().string());
    }
  }
  std::sort(names.begin(), names.end(), natural_less);
  return names;
}

// Stamp encoded in a file name stem, or false.
bool stamp_from_stem(const std::string& stem, bool& seconds_style, int64_t& ns) {
  if (stem.find('.') != std::string::npos) {
    seconds_style = true;
    return parse_seconds_ns(stem, ns);
  }
  seconds_style = false;
  if (stem.size() < 16 || stem.size() > 19) return false;
  const auto r = std::from_chars(stem.data(), stem.data() + stem.size(), ns);
  return r.ec == std::errc() && r.ptr == stem.data() + stem.size();
}

}  // namespace

bool looks_like_image_folder(const std::string& dir) {
  return fs::is_directory(dir) && !image_names(dir).empty();
}

std::unique_ptr<ReplaySource> open_image_folder_source(const std::string& uri,
                                                       const std::string& dir, double fps_override,
                                                       double speed) {
  if (!fs::is_directory(dir)) throw std::runtime_error(dir + ": not a folder");
  const std::vector<std::string> names = image_names(dir);
  if (names.empty()) {
    throw std::runtime_error(dir + ": no image files (png jpg jpeg bmp pgm ppm tif tiff)");
  }
  std::vector<ImageFileSequence::Item> items;
  items.reserve(names.size());
  bool from_names = fps_override <= 0.0;
  bool first_style = false;
  for (size_t i = 0; i < names.size() && from_names; ++i) {
    bool style = false;
    int64_t ns = 0;
    from_names = stamp_from_stem(fs::path(names[i]).stem().string(), style, ns) &&
                 (i == 0 || style == first_style) && (items.empty() || ns > items.back().stamp_ns);
    if (i == 0) first_style = style;
    if (from_names) items.push_back({ns, (fs::path(dir) / names[i]).string()});
  }
  if (!from_names) {
    const double fps = fps_override > 0.0 ? fps_override : kDefaultImageFolderFps;
    items.clear();
    for (size_t i = 0; i < names.size(); ++i) {
      items.push_back(
          {std::llround(static_cast<double>(i) * 1e9 / fps), (fs::path(dir) / names[i]).string()});
    }
  }
  return make_image_replay(uri, "images", std::move(items), std::nullopt, std::nullopt, speed);
}

}  // namespace rdslam
