// SynthSequence: the synthetic camera as a C++ API for tests and tools (issue 5). Built from a
// scenario name or a YAML file plus a seed; renders any frame on demand with exact ground
// truth: image (BGR8), depth (CV_32F metres), object ids (CV_16U), dynamic mask (CV_8U) and
// T_world_cam. The scene (geometry, motions, events, surface queries) is available through
// scene(); docs/synthetic.md describes the coordinate frames.
//
//   SynthSequence seq("rearrange", /*frames=*/300, /*seed=*/1);
//   SynthFrame f;                       // buffers allocated on first use, then reused
//   for (int i = 0; i < seq.frame_count(); ++i) seq.render(i, f);
//   SynthPointFate fate = seq.scene().point_fate(p_world, frame_ref, frame_now);
//
// Ownership: owns its scene and renderer. Threads: render() from one thread at a time;
// const accessors from any thread.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/trajectory.h"
#include "drivers/synth_render.h"
#include "drivers/synth_scene.h"

namespace rdslam {

class SynthSequence {
 public:
  // Throws std::runtime_error on an unknown scenario, a bad YAML file or missing textures.
  explicit SynthSequence(const std::string& scenario_or_yaml, int frames = -1, int64_t seed = -1);
  explicit SynthSequence(SynthScene scene);

  int frame_count() const { return scene_->frame_count; }
  double fps() const { return scene_->fps; }
  const CameraModel& camera() const { return scene_->camera; }
  const SynthScene& scene() const { return *scene_; }
  const std::vector<SynthEvent>& events() const { return scene_->events; }
  const Eigen::Isometry3d& T_world_cam(int index) const { return scene_->T_world_cam.at(index); }
  int64_t stamp_ns(int index) const;
  // T_world_cam of every frame with its stamp (TUM groundtruth.txt content).
  Trajectory ground_truth() const;

  // Renders frame `index` into `out` (buffers reused). False when index is out of range.
  bool render(int index, SynthFrame& out) { return renderer_->render(index, out); }

 private:
  std::unique_ptr<SynthScene> scene_;
  std::unique_ptr<SynthRenderer> renderer_;
};

// Writes the sequence as a TUM-format folder (docs/synthetic.md): rgb/ + rgb.txt, depth/
// (16-bit PNG, 5000 per metre) + depth.txt, mask/, id/, groundtruth.txt, camera.yaml,
// events.yaml. `dir` must not exist or be empty (throws otherwise). `progress` is called
// after each frame with (frames written, total).
void write_synth_dataset(SynthSequence& seq, const std::string& dir,
                         const std::function<void(int, int)>& progress = {});
// The events as YAML text (events.yaml).
std::string synth_events_yaml(const SynthScene& scene);
// A contact sheet: `columns` evenly spaced frames of the sequence, each with its dynamic mask
// overlaid in red and the frame number; `rows` rows. Tiles are scaled to `tile_width` px.
cv::Mat synth_contact_sheet(SynthSequence& seq, int columns = 4, int rows = 1,
                            int tile_width = 320);

}  // namespace rdslam
