// Relocalization with a map at its configured cap (issue 23 item 2): the real Tracker, LOST
// against a map of mapper.max_keyframes (150) keyframes and mapper.max_points (20000) points,
// with place recognition (core/keyframe_database.h, the repository's vocabulary) or with the
// brute-force global matching it replaced (every feature against every point).
//
// The capped map is made from exact ground truth: synth:static_halfsphere (seed 31, not an
// evaluation seed), 300 frames; every even frame is a keyframe contributing 133 points (its
// features spread over the image, positions from the rendered depth), each observed by that
// keyframe and the next two; keyframe vectors from all its features, as the mapper computes
// them. The tracker initializes on the first frames (its own small map), then the capped map
// is published into its matching index and the frames are replayed in order with two frames of
// another place (OpenCV's vtest.avi, a street) in every ten: the first loses tracking, the
// second is a failed relocalization attempt, the next frame of the scene relocalizes, the rest
// are tracked against the capped map. Counters: track() time of the frames processed while LOST
// (lost_p50/p99_ms) and of the tracked frames (track_p50/p99_ms), both against the same capped map;
// relocalized counts the successes.
//
//   ./build/benchmarks/bench_relocalization
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <vector>

#include "core/slam.h"
#include "drivers/synth_sequence.h"

using namespace rdslam;

namespace {

constexpr int kFrames = 300;
constexpr int kPointsPerKeyframe = 133;  // 150 keyframes x 133 = 19950 points: at the cap
// Debian's opencv-doc (as data/textures/LICENSE.md); without it grey frames stand in.
constexpr const char* kForeignVideo = "/usr/share/doc/opencv-doc/examples/data/vtest.avi";

struct Scene {
  std::vector<cv::Mat> gray;  // every frame
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> T_world_cam;
  std::vector<cv::Mat> depth;  // keyframes (even frames) only, else empty
  CameraModel camera;
  std::vector<cv::Mat> foreign;  // frames of another place (OpenCV's vtest.avi), same size
};

const Scene& scene() {
  static const Scene s = [] {
    Scene sc;
    SynthSequence seq("static_halfsphere", kFrames, 31);
    sc.camera = seq.camera();
    SynthFrame f;
    for (int i = 0; i < kFrames; ++i) {
      seq.render(i, f);
      cv::Mat g;
      cv::cvtColor(f.image, g, cv::COLOR_BGR2GRAY);
      sc.gray.push_back(g);
      sc.T_world_cam.push_back(f.T_world_cam);
      sc.depth.push_back(i % 2 == 0 ? f.depth.clone() : cv::Mat());
    }
    cv::VideoCapture video(kForeignVideo);
    cv::Mat bgr, g;
    for (int k = 0; k < 60 && video.read(bgr); ++k) {
      if (k % 2 != 0) continue;
      cv::cvtColor(bgr, g, cv::COLOR_BGR2GRAY);
      cv::resize(g, g, sc.gray[0].size(), 0, 0, cv::INTER_AREA);
      sc.foreign.push_back(g.clone());
    }
    if (sc.foreign.empty()) sc.foreign.push_back(cv::Mat(sc.gray[0].size(), CV_8UC1, 128));
    return sc;
  }();
  return s;
}

// The capped map as a snapshot of epoch `epoch` (places: with the keyframe database).
std::shared_ptr<MapSnapshot> capped_snapshot(const Scene& sc, const SlamParams& params,
                                             const Vocabulary* voc, uint32_t epoch) {
  auto s = std::make_shared<MapSnapshot>();
  s->epoch = epoch;
  s->binary = true;
  FeatureExtractor fx(params.features, sc.camera);
  Features f;
  const PinholeIntrinsics K{sc.camera.fx, sc.camera.fy, sc.camera.cx, sc.camera.cy};
  const int kfs = kFrames / 2;
  std::vector<std::vector<int>> rows_of(static_cast<size_t>(kfs));
  std::unique_ptr<KeyframeDatabaseBuilder> db;
  if (voc) db = std::make_unique<KeyframeDatabaseBuilder>(voc->words());
  BowVector bow;
  Vocabulary::Scratch scratch;
  std::vector<cv::Mat> desc_rows;
  for (int k = 0; k < kfs; ++k) {
    const int i = 2 * k;
    fx.extract(sc.gray[size_t(i)], f);
    if (db) {
      voc->transform(f, bow, scratch);
      db->add(epoch, k, bow);
    }
    const Eigen::Isometry3d& Twc = sc.T_world_cam[size_t(i)];
    Pose Tcw;
    Tcw.R = Twc.rotation().transpose();
    Tcw.t = -Tcw.R * Twc.translation();
    s->kf_ids.push_back(k);
    s->kf_pose.push_back(Tcw);
    const int step = std::max(1, f.count / kPointsPerKeyframe);
    int added = 0;
    for (int j = 0; j < f.count && added < kPointsPerKeyframe; j += step) {
      const cv::Point2f px = f.kps[size_t(j)].pt;
      const float z = sc.depth[size_t(i)].at<float>(cvRound(px.y), cvRound(px.x));
      if (!(z > 0.f)) continue;
      const Eigen::Vector3d pc((f.un[size_t(j)].x - K.cx) / K.fx * z,
                               (f.un[size_t(j)].y - K.cy) / K.fy * z, z);
      const Eigen::Vector3d pw = Twc * pc;
      const int r = s->rows();
      s->ids.push_back(r);
      s->p_world.push_back(pw);
      s->normal.push_back((Twc.translation() - pw).normalized().cast<float>());
      const float d = static_cast<float>(pc.norm());
      const float up =
          static_cast<float>(std::pow(params.features.scale_factor, f.level[size_t(j)]));
      s->max_dist.push_back(d * up * 1.2f);
      s->min_dist.push_back(
          d * up /
          static_cast<float>(std::pow(params.features.scale_factor, params.features.levels - 1)) /
          1.2f);
      desc_rows.push_back(f.desc.row(j).clone());
      s->row_of.emplace(r, r);
      for (int o = k; o < std::min(kfs, k + 3); ++o) rows_of[size_t(o)].push_back(r);
      ++added;
    }
  }
  cv::vconcat(desc_rows, s->desc);
  // Observations (CSR both ways) and each keyframe's point count.
  std::vector<std::vector<int>> obs(size_t(s->rows()));
  s->kf_row_start.push_back(0);
  for (int k = 0; k < kfs; ++k) {
    for (int r : rows_of[size_t(k)]) {
      obs[size_t(r)].push_back(k);
      s->kf_rows.push_back(r);
    }
    s->kf_row_start.push_back(static_cast<int>(s->kf_rows.size()));
    s->kf_points.push_back(static_cast<int>(rows_of[size_t(k)].size()));
  }
  s->obs_start.push_back(0);
  for (const auto& o : obs) {
    s->obs_kf.insert(s->obs_kf.end(), o.begin(), o.end());
    s->obs_start.push_back(static_cast<int>(s->obs_kf.size()));
  }
  if (db) s->places = db->build();
  return s;
}

// CPU time of this thread: on a loaded machine wall time measures the neighbours too.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double x = q * double(v.size() - 1);
  const size_t i = static_cast<size_t>(x);
  return i + 1 < v.size() ? v[i] + (x - double(i)) * (v[i + 1] - v[i]) : v[i];
}

void run(benchmark::State& state, bool places) {
  const Scene& sc = scene();
  SlamParams params;  // defaults: mapper.max_keyframes 150, mapper.max_points 20000
  auto link = make_slam_link(params, 8);
  const std::shared_ptr<const Vocabulary> voc = link->vocabulary;
  if (!places) link->vocabulary.reset();  // the brute-force global matching
  Tracker tracker(params.tracker, params.features, params.mapper.ba, params.parsac, sc.camera, link,
                  params.mapper.max_points, params.mapper.max_keyframes);
  Mapper mapper(params.mapper, params.features, sc.camera, link);
  std::vector<double> lost_ms, track_ms, lost_cpu, track_cpu, reloc_cpu, failed_cpu;
  int relocalized = 0, points = 0;
  for (auto _ : state) {
    Frame frame;
    frame.format = PixelFormat::kGray8;
    TrackingState last = TrackingState::kInitializing;
    int i = 0;
    // Initialization on the first frames, with the mapper (the tracker's own small map).
    for (; i < 60 && last != TrackingState::kTracking; ++i) {
      sc.gray[size_t(i)].copyTo(frame.image);
      frame.stamp_ns = i * 33'333'333LL;
      frame.seq = static_cast<uint64_t>(i);
      last = tracker.track(frame).state;
      while (mapper.step(0)) {
      }
    }
    if (last != TrackingState::kTracking) {
      state.SkipWithError("the tracker did not initialize");
      return;
    }
    // The capped map replaces the mapper's (which does not run from now on).
    auto snap = capped_snapshot(sc, params, places ? voc.get() : nullptr, 0);
    points = snap->rows();
    link->index.publish(std::move(snap));
    for (int n = 0; i < kFrames; ++i, ++n) {
      if (n % 10 < 2) {
        sc.foreign[size_t(n / 10) % sc.foreign.size()].copyTo(frame.image);
      } else {
        sc.gray[size_t(i)].copyTo(frame.image);
      }
      frame.stamp_ns = i * 33'333'333LL;
      frame.seq = static_cast<uint64_t>(i);
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = thread_cpu_ms();
      const TrackResult r = tracker.track(frame);
      const double cpu = thread_cpu_ms() - c0;
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (last == TrackingState::kLost) {
        lost_ms.push_back(ms);
        lost_cpu.push_back(cpu);
        const bool ok = r.state == TrackingState::kRelocalized;
        relocalized += ok;
        (ok ? reloc_cpu : failed_cpu).push_back(cpu);
      } else if (r.state == TrackingState::kTracking) {
        track_ms.push_back(ms);
        track_cpu.push_back(cpu);
      }
      last = r.state;
    }
  }
  state.counters["points"] = points;
  state.counters["lost_frames"] = static_cast<double>(lost_ms.size());
  state.counters["relocalized"] = relocalized;
  state.counters["lost_p50_ms"] = percentile(lost_ms, 0.5);
  state.counters["lost_p99_ms"] = percentile(lost_ms, 0.99);
  state.counters["track_p50_ms"] = percentile(track_ms, 0.5);
  state.counters["track_p99_ms"] = percentile(track_ms, 0.99);
  state.counters["cpu_lost_p50_ms"] = percentile(lost_cpu, 0.5);
  state.counters["cpu_lost_p99_ms"] = percentile(lost_cpu, 0.99);
  state.counters["cpu_relocalized_p50_ms"] = percentile(reloc_cpu, 0.5);
  state.counters["cpu_failed_p50_ms"] = percentile(failed_cpu, 0.5);
  state.counters["cpu_track_p50_ms"] = percentile(track_cpu, 0.5);
  state.counters["cpu_lost_p99_over_track_p50"] =
      percentile(lost_cpu, 0.99) / std::max(1e-9, percentile(track_cpu, 0.5));
  state.counters["lost_p99_over_track_p50"] =
      percentile(lost_ms, 0.99) / std::max(1e-9, percentile(track_ms, 0.5));
}

void BM_RelocalizeCappedMap_Places(benchmark::State& state) {
  run(state, true);
}
void BM_RelocalizeCappedMap_BruteForce(benchmark::State& state) {
  run(state, false);
}

}  // namespace

BENCHMARK(BM_RelocalizeCappedMap_Places)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RelocalizeCappedMap_BruteForce)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
