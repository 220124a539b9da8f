// `synth:SCENARIO` and `synth:path/to/scenario.yaml`: the synthetic camera as a FrameSource.
// Frames are rendered on demand (>= 30 fps at 640x480 on one core, see docs/synthetic.md),
// stamped at 1/fps from t = 0; camera() gives the scene's intrinsics and ground_truth() the
// exact T_world_cam of every frame. Pacing (SourceOptions::speed) is ReplaySource's.
//
// Ownership/threads: as any FrameSource (core/frame_source.h).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "core/frame_source.h"
#include "drivers/source_factory.h"

namespace rdslam {

// `spec` is a scenario name or a YAML path (without the "synth:" prefix; a leading
// "synth:" is accepted too). frames > 0 and seed >= 0 override the scenario's values.
// Throws std::runtime_error naming the spec on failure (start-up boundary).
std::unique_ptr<FrameSource> open_synth_source(const std::string& spec,
                                               const SourceOptions& options, int frames = -1,
                                               int64_t seed = -1);

}  // namespace rdslam
