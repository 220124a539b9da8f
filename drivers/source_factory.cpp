// open_source(): URI parsing, bare-path auto-detection, and the intrinsics precedence
// (issue 4, item 1): the dataset's own calibration, else a camera.yaml beside the data, else
// the configuration's camera section; `--set camera.*` (SourceOptions::camera_overridden)
// wins over all of them.
//
// URI grammar: SCHEME:PATH[?key=value[&key=value...]] or a bare PATH. Each scheme is one
// row of kSchemes below; a new source kind adds one row (and its include).
#include "drivers/source_factory.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <initializer_list>
#include <map>
#include <stdexcept>

#include "core/log.h"
#include "drivers/dataset_euroc.h"
#include "drivers/dataset_kitti.h"
#include "drivers/dataset_tum.h"
#include "drivers/image_folder_source.h"
#include "drivers/lcm_image_source.h"
#include "drivers/libcamera_source.h"
#include "drivers/synth_source.h"
#include "drivers/v4l2_source.h"
#include "drivers/video_source.h"

namespace rdslam {

namespace fs = std::filesystem;

namespace {

struct SourceUri {
  std::string uri;     // as given
  std::string scheme;  // "tum", ...; after auto-detection for bare paths
  std::string path;    // the part after "scheme:", without the query
  std::map<std::string, std::string> params;

  // Takes a numeric parameter out of `params` (unknown leftovers are an error later).
  double number(const char* key, double fallback) {
    const auto it = params.find(key);
    if (it == params.end()) return fallback;
    char* end = nullptr;
    const double v = std::strtod(it->second.c_str(), &end);
    if (it->second.empty() || !end || *end != '\0' || !std::isfinite(v) || v <= 0.0) {
      throw std::runtime_error("source '" + uri + "': parameter " + key + "=" + it->second +
                               " is not a positive number");
    }
    params.erase(it);
    return v;
  }
  // Takes a parameter that must be one of `allowed`.
  std::string choice(const char* key, std::initializer_list<const char*> allowed,
                     const char* fallback) {
    const auto it = params.find(key);
    if (it == params.end()) return fallback;
    const std::string v = it->second;
    std::string list;
    for (const char* a : allowed) {
      if (v == a) {
        params.erase(it);
        return v;
      }
      list += (list.empty() ? "" : ", ") + std::string(a);
    }
    throw std::runtime_error("source '" + uri + "': parameter " + key + "=" + v +
                             " is not allowed; allowed: " + list);
  }
};

// A source and the folder its camera.yaml would sit in ("" when it has none, e.g. cameras).
struct Opened {
  std::unique_ptr<FrameSource> source;
  std::string data_dir;
};

struct Scheme {
  const char* name;
  const char* what;  // for error messages and docs/sources.md
  Opened (*open)(SourceUri& u, const SourceOptions& o);
};

// ---- one row per source kind -------------------------------------------------------------
const Scheme kSchemes[] = {
    {"tum", "TUM RGB-D folder (rgb.txt)",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       return {open_tum_source(u.uri, u.path, o.speed), u.path};
     }},
    {"euroc", "EuRoC/ASL folder (mav0/cam0)",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       return {open_euroc_source(u.uri, u.path, o.speed), u.path};
     }},
    {"kitti", "KITTI odometry sequence (image_0/ or image_l/), ?rate_hz=",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       const double rate = u.number("rate_hz", o.kitti_rate_hz);
       return {open_kitti_source(u.uri, u.path, rate, o.speed), u.path};
     }},
    {"images", "folder of images, ?fps=",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       const double fps = u.number("fps", 0.0);
       return {open_image_folder_source(u.uri, u.path, fps, o.speed), u.path};
     }},
    {"video", "video file (OpenCV videoio), ?fps=",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       const double fps = u.number("fps", 0.0);
       const fs::path parent = fs::path(u.path).parent_path();
       return {open_video_source(u.uri, u.path, fps, o.speed),
               parent.empty() ? "." : parent.string()};
     }},
    {"lcm", "libbot2 bot_core.image_t on an LCM channel, ?format=gray|bgr",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       const bool bgr = u.choice("format", {"gray", "bgr"}, "gray") == "bgr";
       // The frame size is the configured camera's: known before the first message.
       return {open_lcm_image_source(u.uri, u.path, o.lcm_url, o.config_camera.width,
                                     o.config_camera.height,
                                     bgr ? PixelFormat::kBgr8 : PixelFormat::kGray8),
               ""};
     }},
    {"v4l2", "V4L2 (USB/UVC) camera device, e.g. v4l2:/dev/video0; config section v4l2",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       return {open_v4l2_source(u.path, o.v4l2, o.config_camera.width, o.config_camera.height), ""};
     }},
    {"libcamera", "libcamera camera by index or id, e.g. libcamera:0; config section libcamera",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
#ifdef RDSLAM_HAVE_LIBCAMERA
       return {open_libcamera_source(u.path, o.libcamera, o.config_camera.width,
                                     o.config_camera.height),
               ""};
#else
       (void)o;
       throw std::runtime_error("source '" + u.uri +
                                "': this rdslam was built without libcamera (install "
                                "libcamera-dev and rebuild; docs/cameras.md)");
#endif
     }},
    {"synth", "synthetic dynamic scene: scenario name or YAML file, ?frames=&seed=",
     [](SourceUri& u, const SourceOptions& o) -> Opened {
       const int frames = static_cast<int>(u.number("frames", -1));
       const int64_t seed = static_cast<int64_t>(u.number("seed", -1));
       return {open_synth_source(u.path, o, frames, seed), ""};
     }},
};

std::string scheme_list() {
  std::string s;
  for (const auto& sc : kSchemes) s += (s.empty() ? "" : ", ") + std::string(sc.name) + ":";
  return s;
}

const Scheme* find_scheme(const std::string& name) {
  for (const auto& sc : kSchemes) {
    if (name == sc.name) return &sc;
  }
  return nullptr;
}

// What a bare path is, from its content.
std::string detect_scheme(const std::string& path) {
  if (fs::is_directory(path)) {
    if (looks_like_tum(path)) return "tum";
    if (looks_like_euroc(path)) return "euroc";
    if (looks_like_kitti(path)) return "kitti";
    if (looks_like_image_folder(path)) return "images";
    throw std::runtime_error(
        "source '" + path +
        "': folder is not a TUM (rgb.txt), EuRoC (mav0/cam0/data.csv) or KITTI (image_0/, "
        "image_l/) sequence and holds no images");
  }
  if (fs::is_character_file(path)) return "v4l2";  // /dev/videoN, /dev/v4l/by-id/...
  if (fs::is_regular_file(path)) {
    if (has_video_extension(path)) return "video";
    throw std::runtime_error("source '" + path +
                             "': a file that is not a known video type; use video:" + path +
                             " to force it");
  }
  throw std::runtime_error("source '" + path + "': no such file or folder, and not a URI (" +
                           scheme_list() + ")");
}

SourceUri parse_uri(const std::string& uri) {
  SourceUri u;
  u.uri = uri;
  std::string rest = uri;
  const size_t colon = uri.find(':');
  bool has_scheme = false;
  if (colon != std::string::npos && colon > 0) {
    const std::string head = uri.substr(0, colon);
    const bool word = std::all_of(head.begin(), head.end(), [](char c) {
      return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    });
    if (word && find_scheme(head)) {
      has_scheme = true;
      u.scheme = head;
      rest = uri.substr(colon + 1);
    } else if (word && !fs::exists(uri)) {
      throw std::runtime_error("source '" + uri + "': unknown scheme '" + head +
                               "'; known: " + scheme_list() + " or a bare path");
    }
  }
  const size_t q = rest.find('?');
  if (q != std::string::npos && !(u.scheme.empty() && fs::exists(rest))) {
    const std::string query = rest.substr(q + 1);
    rest = rest.substr(0, q);
    size_t start = 0;
    while (start <= query.size()) {
      size_t amp = query.find('&', start);
      if (amp == std::string::npos) amp = query.size();
      const std::string kv = query.substr(start, amp - start);
      const size_t eq = kv.find('=');
      if (eq == std::string::npos || eq == 0) {
        throw std::runtime_error("source '" + uri + "': parameter '" + kv + "' is not key=value");
      }
      u.params[kv.substr(0, eq)] = kv.substr(eq + 1);
      start = amp + 1;
    }
  }
  u.path = rest;
  if (u.path.empty()) throw std::runtime_error("source '" + uri + "': empty path");
  if (!has_scheme) u.scheme = detect_scheme(u.path);
  return u;
}

// Presents a resolved camera in place of the source's own (start-up decision).
class CameraResolvedSource : public FrameSource {
 public:
  CameraResolvedSource(std::unique_ptr<FrameSource> inner, CameraModel camera)
      : inner_(std::move(inner)), camera_(std::move(camera)) {}
  SourceStatus read(Frame& out, int timeout_ms) override { return inner_->read(out, timeout_ms); }
  const SourceInfo& info() const override { return inner_->info(); }
  std::optional<CameraModel> camera() const override { return camera_; }
  std::optional<Trajectory> ground_truth() const override { return inner_->ground_truth(); }
  SourceCounters counters() const override { return inner_->counters(); }

 private:
  std::unique_ptr<FrameSource> inner_;
  CameraModel camera_;
};

const char* format_name(PixelFormat f) {
  return f == PixelFormat::kGray8 ? "grey" : "BGR";
}

}  // namespace

std::unique_ptr<FrameSource> open_source(const std::string& uri, const SourceOptions& options) {
  if (!(options.speed >= 0.0) || !std::isfinite(options.speed)) {
    throw std::runtime_error("source '" + uri + "': speed must be >= 0 (0 = as fast as read)");
  }
  SourceUri u = parse_uri(uri);
  Opened opened = find_scheme(u.scheme)->open(u, options);
  if (!u.params.empty()) {
    throw std::runtime_error("source '" + uri + "': unknown parameter '" + u.params.begin()->first +
                             "' for " + u.scheme + ":");
  }
  std::unique_ptr<FrameSource> src = std::move(opened.source);

  // Intrinsics precedence: --set camera.* > dataset calibration > camera.yaml > config.
  const std::optional<CameraModel> own = src->camera();
  std::optional<CameraModel> resolved;
  std::string origin;
  if (options.camera_overridden) {
    resolved = options.config_camera;
    origin = "the configuration (--set camera.* overrides the source)";
  } else if (own) {
    origin = "the dataset's calibration";
  } else {
    const fs::path yaml = fs::path(opened.data_dir.empty() ? "" : opened.data_dir) / "camera.yaml";
    if (!opened.data_dir.empty() && fs::is_regular_file(yaml)) {
      resolved = read_camera_yaml(yaml.string());
      origin = yaml.string();
    } else {
      resolved = options.config_camera;
      origin = "the configuration's camera section";
    }
  }
  if (resolved) src = std::make_unique<CameraResolvedSource>(std::move(src), *resolved);

  const SourceInfo& info = src->info();
  const CameraModel cam = *src->camera();
  RDSLAM_LOG_INFO(
      "source %s: %s %dx%d %s, %.3g fps, %lld frames%s; camera from %s", info.uri.c_str(),
      info.kind.c_str(), info.width, info.height, format_name(info.format), info.nominal_fps,
      static_cast<long long>(info.frame_count),
      info.live ? (options.speed > 0 ? ", paced (real time)" : ", live") : "", origin.c_str());
  if (info.width > 0 && (cam.width != info.width || cam.height != info.height)) {
    RDSLAM_LOG_WARN(
        "source %s: frames are %dx%d but the camera (from %s) is %dx%d: the "
        "intrinsics do not belong to these images",
        info.uri.c_str(), info.width, info.height, origin.c_str(), cam.width, cam.height);
  }
  return src;
}

}  // namespace rdslam
