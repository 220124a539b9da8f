#include "drivers/synth_sequence.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "core/timestamp.h"
#include "drivers/replay_source.h"

namespace rdslam {

namespace fs = std::filesystem;

SynthSequence::SynthSequence(const std::string& scenario_or_yaml, int frames, int64_t seed)
    : SynthSequence(load_synth_scene(scenario_or_yaml, frames, seed)) {}

SynthSequence::SynthSequence(SynthScene scene)
    : scene_(std::make_unique<SynthScene>(std::move(scene))),
      renderer_(std::make_unique<SynthRenderer>(*scene_)) {}

int64_t SynthSequence::stamp_ns(int index) const {
  return static_cast<int64_t>(std::llround(index * 1e9 / scene_->fps));
}

Trajectory SynthSequence::ground_truth() const {
  Trajectory t;
  t.reserve(scene_->frame_count);
  for (int i = 0; i < scene_->frame_count; ++i) {
    StampedPose p;
    p.stamp_ns = stamp_ns(i);
    p.p_world_cam = scene_->T_world_cam[i].translation();
    p.q_world_cam = Eigen::Quaterniond(scene_->T_world_cam[i].linear()).normalized();
    t.push_back(p);
  }
  return t;
}

std::string synth_events_yaml(const SynthScene& scene) {
  std::ostringstream os;
  os << "# rdslam synthetic sequence: what changes, when (frames inclusive, 0-based).\n"
     << "# kind: move (object moving), appear, disappear, light (spot light on),\n"
     << "# exposure (global gain changing). object_id matches the id/ images.\n"
     << "scenario: " << scene.name << "\n"
     << "seed: " << scene.seed << "\n"
     << "fps: " << scene.fps << "\n"
     << "frames: " << scene.frame_count << "\n"
     << "objects:\n";
  for (const auto& o : scene.objects) {
    os << "  - {id: " << o.id << ", name: " << o.name
       << ", dynamic_from: " << (o.first_change == INT_MAX ? -1 : o.first_change);
    if (!o.variant.empty()) os << ", variant: " << o.variant;
    os << "}\n";
  }
  os << "events:\n";
  if (scene.events.empty()) os << "  []\n";
  for (const auto& e : scene.events) {
    os << "  - {object_id: " << e.object_id << ", object: " << e.object_name << ", kind: " << e.kind
       << ", first_frame: " << e.first_frame << ", last_frame: " << e.last_frame << "}\n";
  }
  return os.str();
}

void write_synth_dataset(SynthSequence& seq, const std::string& dir,
                         const std::function<void(int, int)>& progress) {
  if (fs::exists(dir) && !(fs::is_directory(dir) && fs::is_empty(dir)))
    throw std::runtime_error("synth: output '" + dir +
                             "' exists and is not empty; refusing to overwrite");
  for (const char* sub : {"rgb", "depth", "mask", "id"})
    fs::create_directories(fs::path(dir) / sub);
  std::ofstream rgb_txt(fs::path(dir) / "rgb.txt"), depth_txt(fs::path(dir) / "depth.txt");
  if (!rgb_txt || !depth_txt) throw std::runtime_error("synth: cannot write into '" + dir + "'");
  const std::string name = seq.scene().name;
  rgb_txt << "# color images (rdslam synth " << name << ")\n# timestamp filename\n";
  depth_txt << "# depth maps (rdslam synth " << name
            << "), 16-bit PNG, 5000 units per metre\n# timestamp filename\n";
  SynthFrame f;
  cv::Mat depth16;
  char file[64];
  for (int i = 0; i < seq.frame_count(); ++i) {
    seq.render(i, f);
    const std::string stamp = format_seconds_ns(f.stamp_ns);
    std::snprintf(file, sizeof(file), "%06d.png", i);
    // TUM depth convention: 16-bit, 5000 per metre (0 = no measurement).
    f.depth.convertTo(depth16, CV_16U, 5000.0);
    const std::pair<const char*, const cv::Mat*> outs[] = {
        {"rgb", &f.image}, {"depth", &depth16}, {"mask", &f.mask}, {"id", &f.ids}};
    for (const auto& o : outs) {
      const fs::path p = fs::path(dir) / o.first / file;
      if (!cv::imwrite(p.string(), *o.second))
        throw std::runtime_error("synth: cannot write " + p.string());
    }
    rgb_txt << stamp << " rgb/" << file << "\n";
    depth_txt << stamp << " depth/" << file << "\n";
    if (progress) progress(i + 1, seq.frame_count());
  }
  write_trajectory_tum((fs::path(dir) / "groundtruth.txt").string(), seq.ground_truth());
  write_camera_yaml((fs::path(dir) / "camera.yaml").string(), seq.camera());
  std::ofstream ev(fs::path(dir) / "events.yaml");
  ev << synth_events_yaml(seq.scene());
  if (!rgb_txt || !depth_txt || !ev)
    throw std::runtime_error("synth: write error in '" + dir + "'");
}

cv::Mat synth_contact_sheet(SynthSequence& seq, int columns, int rows, int tile_width) {
  const int n = std::max(1, columns * rows);
  const CameraModel& cam = seq.camera();
  const int tile_h = tile_width * cam.height / cam.width;
  cv::Mat sheet(rows * tile_h, columns * tile_width, CV_8UC3, cv::Scalar(0, 0, 0));
  SynthFrame f;
  cv::Mat over, tile;
  for (int k = 0; k < n; ++k) {
    const int index =
        static_cast<int>(std::lround((seq.frame_count() - 1) * (k + 0.5) / static_cast<double>(n)));
    seq.render(index, f);
    // Dynamic mask in red at 50%, outlined so thin regions stay visible.
    f.image.copyTo(over);
    over.setTo(cv::Scalar(0, 0, 255), f.mask);
    cv::addWeighted(f.image, 0.5, over, 0.5, 0.0, over);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(f.mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    cv::drawContours(over, contours, -1, cv::Scalar(0, 0, 255), 2);
    cv::resize(over, tile, cv::Size(tile_width, tile_h), 0, 0, cv::INTER_AREA);
    const std::string label =
        (k == 0 ? seq.scene().name + "  " : std::string()) + "frame " + std::to_string(index);
    cv::putText(tile, label, {6, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 3);
    cv::putText(tile, label, {6, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1);
    tile.copyTo(
        sheet(cv::Rect((k % columns) * tile_width, (k / columns) * tile_h, tile_width, tile_h)));
  }
  return sheet;
}

}  // namespace rdslam
