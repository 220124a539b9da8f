// Schedule error of real-time (hardware-in-the-loop) replay, issue 4 item 2: a 30 fps
// sequence replayed at --speed 1 by a consumer that keeps up. For every frame the error is
// (CLOCK_MONOTONIC when read() returned) - (the frame's due time t0 + (stamp - stamp0)/speed),
// so it includes the clock_nanosleep wake-up latency and the copy into the caller's buffer.
// Goal: p99 within 2 ms.
//
// Two sequences: in-memory frames (pure pacing cost) and PNG files decoded on the fly
// (640x480 grey, the decode happens before the deadline). Each run replays 150 frames (5 s).
//
//   ./build/benchmarks/bench_replay_pacing            (counters p50_us, p99_us, max_us)
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "drivers/replay_source.h"

using namespace rdslam;

namespace {

constexpr int kFrames = 150;
constexpr int64_t kPeriodNs = 1000000000LL / 30;

class MemorySequence : public RecordedSequence {
 public:
  MemorySequence() : image_(480, 640, CV_8UC1, cv::Scalar(7)) {}
  bool stamp(int64_t i, int64_t& s) const override {
    if (i < 0 || i >= kFrames) return false;
    s = i * kPeriodNs;
    return true;
  }
  SourceStatus load(int64_t i, cv::Mat& out) override {
    if (i >= kFrames) return SourceStatus::kEndOfStream;
    image_.copyTo(out);
    return SourceStatus::kOk;
  }

 private:
  cv::Mat image_;
};

std::vector<ImageFileSequence::Item> png_items(const std::string& dir) {
  std::filesystem::create_directories(dir);
  cv::Mat img(480, 640, CV_8UC1);
  cv::RNG rng(1);
  std::vector<ImageFileSequence::Item> items;
  for (int i = 0; i < kFrames; ++i) {
    const std::string path = dir + "/" + std::to_string(i) + ".png";
    if (i < 10) {  // 10 distinct textured images, reused: realistic decode cost
      rng.fill(img, cv::RNG::NORMAL, 128, 40);
      cv::imwrite(path, img);
    } else {
      std::filesystem::copy_file(dir + "/" + std::to_string(i % 10) + ".png", path,
                                 std::filesystem::copy_options::overwrite_existing);
    }
    items.push_back({i * kPeriodNs, path});
  }
  return items;
}

void report(benchmark::State& state, std::vector<double>& err_us, uint64_t skipped) {
  std::sort(err_us.begin(), err_us.end());
  auto pct = [&](double p) {
    return err_us[std::min(err_us.size() - 1, static_cast<size_t>(p * (err_us.size() - 1) + 0.5))];
  };
  state.counters["frames"] = static_cast<double>(err_us.size());
  state.counters["p50_us"] = pct(0.50);
  state.counters["p99_us"] = pct(0.99);
  state.counters["max_us"] = err_us.back();
  state.counters["skipped"] = static_cast<double>(skipped);
}

void run(benchmark::State& state, const std::function<std::unique_ptr<RecordedSequence>()>& make) {
  std::vector<double> err_us;
  uint64_t skipped = 0;
  for (auto _ : state) {
    SourceInfo info;
    info.width = 640;
    info.height = 480;
    info.format = PixelFormat::kGray8;
    info.frame_count = kFrames;
    ReplaySource src(make(), info, std::nullopt, std::nullopt, /*speed=*/1.0);
    Frame f;
    f.image.create(480, 640, CV_8UC1);
    MonoClock& clock = system_mono_clock();
    while (src.read(f, 1000) == SourceStatus::kOk) {
      const int64_t now = clock.now_ns();
      err_us.push_back(static_cast<double>(now - f.arrival_mono_ns) / 1e3);
      benchmark::DoNotOptimize(f.image.data);
    }
    skipped += src.counters().skipped;
  }
  report(state, err_us, skipped);
}

void BM_ReplaySchedule30fpsMemory(benchmark::State& state) {
  run(state, [] { return std::make_unique<MemorySequence>(); });
}

void BM_ReplaySchedule30fpsPng(benchmark::State& state) {
  const std::string dir = std::filesystem::temp_directory_path().string() +
                          "/rdslam_bench_replay_" + std::to_string(getpid());
  const auto items = png_items(dir);
  run(state,
      [&] { return std::make_unique<ImageFileSequence>(items, PixelFormat::kGray8, 640, 480); });
  std::filesystem::remove_all(dir);
}

}  // namespace

BENCHMARK(BM_ReplaySchedule30fpsMemory)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_ReplaySchedule30fpsPng)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_MAIN();
