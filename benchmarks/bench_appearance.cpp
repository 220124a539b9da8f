// Eq. (2)'s appearance difference (core/change_detection.h, appearance_difference()) against
// its reference definition (tests/support/appearance_reference.h, the plain loops it replaced):
// the map updater's defaults (11x11 window, normalised) on two frames of synth:rigid_object
// three frames apart (the map updater's check_every_n_frames), in colour (BGR, as the synthetic
// scenes) and grey (as KITTI), search_d 0, 1 (the ray search's), 2 (the default) and 4. x' = x
// on 400 pixels of a grid over the frame whose windows have texture; accept = -inf (the minimum
// over every shift, the worst case) or tau_c_relative 0.8 (the map updater's calls: stop at the
// first shift that matches). One call per iteration, cycling over the pixels.
//   ./build/benchmarks/bench_appearance --benchmark_repetitions=5
//   --benchmark_report_aggregates_only=true     (the median rows: docs/benchmarks.md)
#include <benchmark/benchmark.h>

#include <limits>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "core/change_detection.h"
#include "drivers/synth_sequence.h"
#include "tests/support/appearance_reference.h"

namespace rdslam {
namespace {

struct Pair {
  cv::Mat kf[2], cur[2];                   // [0] grey, [1] BGR
  std::vector<Eigen::Vector2d> points[2];  // textured windows, per colour mode
};

const Pair& frames() {
  static const Pair p = [] {
    Pair q;
    SynthSequence seq("rigid_object");
    SynthFrame f;
    seq.render(30, f);
    q.kf[1] = f.image.clone();
    seq.render(33, f);
    q.cur[1] = f.image.clone();
    cv::cvtColor(q.kf[1], q.kf[0], cv::COLOR_BGR2GRAY);
    cv::cvtColor(q.cur[1], q.cur[0], cv::COLOR_BGR2GRAY);
    const int cols = q.kf[0].cols, rows = q.kf[0].rows;
    // Pixels of a 40 x 40 grid whose window has texture (the map updater checks features: a
    // flat window returns +inf at once), at most 400.
    const ChangeDetectionParams params;
    constexpr double kInf = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 2; ++c) {
      for (int i = 0; i < 40 && q.points[c].size() < 400; ++i) {
        for (int j = 0; j < 40 && q.points[c].size() < 400; ++j) {
          const Eigen::Vector2d x(20.3 + (cols - 40.0) * j / 39.0, 20.6 + (rows - 40.0) * i / 39.0);
          if (std::isfinite(test::reference_appearance_difference(q.kf[c], x, q.cur[c], x, 1.0,
                                                                  params.window, 4, true, -kInf))) {
            q.points[c].push_back(x);
          }
        }
      }
    }
    return q;
  }();
  return p;
}

// range(0): 0 reference, 1 optimised; range(1): 0 grey, 1 BGR; range(2): search_d;
// range(3): 0 accept = -inf, 1 accept = 0.8.
void BM_AppearanceDifference(benchmark::State& state) {
  const Pair& p = frames();
  const bool optimised = state.range(0) == 1;
  const int colour = static_cast<int>(state.range(1));
  const int search_d = static_cast<int>(state.range(2));
  const double accept = state.range(3) ? ChangeDetectionParams{}.tau_c_relative
                                       : -std::numeric_limits<double>::infinity();
  const ChangeDetectionParams params;
  size_t i = 0;
  int64_t accepted = 0;
  for (auto _ : state) {
    const Eigen::Vector2d& x = p.points[colour][i];
    const double d =
        optimised ? appearance_difference(p.kf[colour], x, p.cur[colour], x, 1.0, params.window,
                                          search_d, params.normalise_appearance, accept)
                  : test::reference_appearance_difference(p.kf[colour], x, p.cur[colour], x, 1.0,
                                                          params.window, search_d,
                                                          params.normalise_appearance, accept);
    benchmark::DoNotOptimize(d);
    accepted += d <= ChangeDetectionParams{}.tau_c_relative;
    i = (i + 1) % p.points[colour].size();
  }
  state.SetLabel(std::string(optimised ? "optimised" : "reference") +
                 (colour ? ", BGR" : ", grey") + ", d " + std::to_string(search_d) +
                 (state.range(3) ? ", accept 0.8" : ", min"));
  // The share of windows that match (<= tau_c_relative): with `accept`, the ones that stop early.
  state.counters["match"] =
      benchmark::Counter(static_cast<double>(accepted), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_AppearanceDifference)
    ->ArgsProduct({{0, 1}, {0, 1}, {0, 1, 2, 4}, {0, 1}})
    ->Unit(benchmark::kMicrosecond)
    ->MinTime(0.3);

}  // namespace
}  // namespace rdslam

BENCHMARK_MAIN();
