// Per-frame cost of the ORB front end (core/features.h) with and without the per-cell FAST
// fallback (features.min_fast_threshold, features.fallback_cell_corners): one extraction per
// iteration, cycling over 30 frames of each source (KITTI 06 excerpt 1226x370, synth
// static_xyz and synth:dim's darkest second, 640x480). Frames are loaded before timing.
//   ./build/benchmarks/bench_features --benchmark_repetitions=10
//   --benchmark_report_aggregates_only=true     (the median row: docs/benchmarks.md)
#include <benchmark/benchmark.h>

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "core/features.h"
#include "drivers/synth_sequence.h"

namespace rdslam {
namespace {

constexpr int kFrames = 30;

struct Clip {
  std::vector<cv::Mat> grey;
  std::string error;
};

Clip kitti() {
  Clip c;
  const std::string dir = RDSLAM_SHARED_DIR "/data/kitti06_excerpt/image_l";
  for (int i = 0; i < kFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "/%06d.png", i);
    cv::Mat img = cv::imread(dir + name, cv::IMREAD_GRAYSCALE);
    if (img.empty()) {
      c.error = dir + name + " not found";
      return c;
    }
    c.grey.push_back(img);
  }
  return c;
}

Clip synth(const std::string& scenario, int first) {
  Clip c;
  SynthSequence seq(scenario);
  SynthFrame f;
  for (int i = first; i < first + kFrames; ++i) {
    seq.render(i, f);
    cv::Mat g;
    cv::cvtColor(f.image, g, cv::COLOR_BGR2GRAY);
    c.grey.push_back(g);
  }
  return c;
}

const Clip& clip(int which) {
  static const Clip clips[3] = {kitti(), synth("static_xyz", 0), synth("dim", 165)};
  return clips[which];
}

// range(0): 0 KITTI, 1 static_xyz, 2 dim (exposure 0.15); range(1): 1 fallback as configured
// by default, 0 off (min_fast_threshold = fast_threshold).
void BM_ExtractOrb(benchmark::State& state) {
  const Clip& c = clip(static_cast<int>(state.range(0)));
  if (!c.error.empty()) {
    state.SkipWithError(c.error.c_str());
    return;
  }
  FeatureParams p;
  if (state.range(1) == 0) p.min_fast_threshold = p.fast_threshold;
  CameraModel cam;
  cam.width = c.grey[0].cols;
  cam.height = c.grey[0].rows;
  cam.cx = (cam.width - 1) / 2.0;
  cam.cy = (cam.height - 1) / 2.0;
  FeatureExtractor ex(p, cam);
  Features f;
  ex.extract(c.grey[0], f);  // warm-up: buffers reach their capacity
  size_t i = 0;
  int64_t features = 0;
  for (auto _ : state) {
    ex.extract(c.grey[i], f);
    features += f.count;
    i = (i + 1) % c.grey.size();
  }
  static const char* names[3] = {"kitti06", "static_xyz", "dim"};
  state.SetLabel(std::string(names[state.range(0)]) +
                 (state.range(1) ? ", fallback" : ", no fallback"));
  state.counters["features"] =
      benchmark::Counter(static_cast<double>(features), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_ExtractOrb)
    ->ArgsProduct({{0, 1, 2}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

}  // namespace
}  // namespace rdslam

BENCHMARK_MAIN();
