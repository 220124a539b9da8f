#include "firmware_app/bench_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "core/latency_histogram.h"
#include "core/slam.h"
#include "drivers/preloaded_frames.h"
#include "drivers/source_factory.h"
#include "firmware_app/cli.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/report.h"

namespace rdslam {

namespace {

// Ends a source after `limit` frames (--frames): benchmarks a prefix of a long recording
// without copying it. Forwards everything else to the wrapped source.
class LimitedSource : public FrameSource {
 public:
  LimitedSource(FrameSource& inner, int64_t limit) : inner_(inner), limit_(limit) {
    info_ = inner.info();
    if (limit_ > 0 && (info_.frame_count < 0 || info_.frame_count > limit_)) {
      info_.frame_count = limit_;
    }
  }
  SourceStatus read(Frame& out, int timeout_ms) override {
    if (limit_ > 0 && delivered_ >= limit_) return SourceStatus::kEndOfStream;
    const SourceStatus s = inner_.read(out, timeout_ms);
    if (s == SourceStatus::kOk) ++delivered_;
    return s;
  }
  const SourceInfo& info() const override { return info_; }
  std::optional<CameraModel> camera() const override { return inner_.camera(); }
  std::optional<Trajectory> ground_truth() const override { return inner_.ground_truth(); }
  SourceCounters counters() const override { return inner_.counters(); }

 private:
  FrameSource& inner_;
  int64_t limit_;
  int64_t delivered_ = 0;
  SourceInfo info_;
};

// Times the tracker stage itself, split into the tracker's own work and the time it blocked
// waiting for the mapper at keyframes (tracker.sync_mapper in lossless replay): the issue's
// tracker budget is about the former; the pipeline's histogram holds the sum.
class TimedTracker : public TrackerStage {
 public:
  explicit TimedTracker(TrackerStage& inner) : inner_(inner) {}
  TrackResult track(const Frame& frame) override {
    const auto t0 = std::chrono::steady_clock::now();
    const int64_t c0 = thread_cpu_ns();
    TrackResult r = inner_.track(frame);
    cpu_.record_ns(thread_cpu_ns() - c0);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const double wait = std::min(ms, std::max(0.0, r.mapper_wait_ms));
    work_.record_ns(static_cast<int64_t>((ms - wait) * 1e6));
    if (wait > 0) wait_.record_ns(static_cast<int64_t>(wait * 1e6));
    return r;
  }
  LatencyHistogram::Snapshot work() const { return work_.snapshot(); }
  LatencyHistogram::Snapshot wait() const { return wait_.snapshot(); }
  LatencyHistogram::Snapshot cpu() const { return cpu_.snapshot(); }

 private:
  static int64_t thread_cpu_ns() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
  }
  TrackerStage& inner_;
  LatencyHistogram work_, wait_, cpu_;
};

void write_stage(JsonWriter& w, const char* name, double p50, double p99) {
  w.begin_object(name).value("p50", p50).value("p99", p99).end_object();
}

void write_snapshot(JsonWriter& w, const char* name, const LatencyHistogram::Snapshot& s) {
  write_stage(w, name, s.percentile_ms(0.5), s.percentile_ms(0.99));
}

void print_stage(const char* name, double p50, double p99, const char* note) {
  std::printf("  %-22s p50 %8.2f ms  p99 %8.2f ms  %s\n", name, p50, p99, note);
}

}  // namespace

int bench_pipeline(int argc, char** argv) {
  std::string uri, config_path;
  std::vector<std::string> overrides;
  bool json = false, single_thread = false, async_mapper = false, no_preload = false;
  double frames_opt = 0;
  ArgParser p(
      "rdslam bench pipeline SOURCE [--json] [--config F] [--set K=V ...] [--frames N] "
      "[--single-thread] [--async-mapper] [--no-preload]",
      "Run the SLAM pipeline on SOURCE as fast as possible (lossless: no frame dropped) and\n"
      "report per-stage times (p50, p99), throughput fps, capture-to-publish latency and\n"
      "peak RSS (issue 10). Feature mode: --set features.mode=orb|sift.\n"
      "SOURCE's frames are first read into memory (untimed), so the numbers measure SLAM,\n"
      "not the synth: renderer or the image decoder; --no-preload times the source too.");
  p.positional("SOURCE", &uri, "frame source URI, e.g. synth:static_xyz or kitti:DIR");
  p.config_options(&config_path, &overrides);
  p.flag("--json", &json,
         "print JSON: the common report keys plus stages {tracker, tracker_cpu, mapper, capture,\n"
         "publish; threaded: tracker_total, tracker_wait}");
  p.option("--frames", &frames_opt, "N", "process at most N frames (default: all)");
  p.flag("--no-preload", &no_preload,
         "read SOURCE while timing (capture then includes rendering or decoding)");
  p.flag("--single-thread", &single_thread,
         "run tracker and mapper alternately in this thread (run_offline): deterministic,\n"
         "for `valgrind --tool=callgrind` instruction counts per frame");
  p.flag("--async-mapper", &async_mapper,
         "do not let the tracker wait for the mapper at keyframes (as `rdslam run` live);\n"
         "default waits, as `rdslam replay` does, so tracking matches the offline result");
  if (!p.parse(argc, argv)) return 0;
  if (frames_opt < 0 || frames_opt > 1e9) throw UsageError("--frames: must be in [0, 1e9]");
  AppConfig cfg = load_cli_config(config_path, overrides);

  SourceOptions so = make_source_options(cfg, overrides, 0.0);
  std::unique_ptr<FrameSource> opened = open_source(uri, so);
  LimitedSource limited(*opened, static_cast<int64_t>(frames_opt));
  // Every frame in memory before timing (drivers/preloaded_frames.h): the benchmark then
  // measures the SLAM stages, not the synthetic renderer or the PNG decoder.
  std::unique_ptr<PreloadedFrames> frames;
  std::unique_ptr<PreloadedFrames::Reader> preloaded;
  if (!no_preload) {
    frames = std::make_unique<PreloadedFrames>(limited);
    preloaded = std::make_unique<PreloadedFrames::Reader>(*frames);
  }
  FrameSource& source = preloaded ? static_cast<FrameSource&>(*preloaded) : limited;
  const double preload_mb = frames ? frames->megabytes() : 0.0;
  const CameraModel camera =
      (!so.camera_overridden && source.camera()) ? *source.camera() : cfg.camera;
  // Threaded lossless replay waits for the mapper at keyframes as `rdslam replay` does. The
  // single-thread driver already runs the mapper after every frame; a tracker that waited
  // there would only time out (the mapper cannot run while the tracker blocks).
  cfg.slam.tracker.sync_mapper = !single_thread && !async_mapper;
  cfg.slam.parsac = cfg.parsac;
  const SourceInfo info = source.info();

  RunReport report;
  std::vector<TrackingState> states;
  std::vector<double> latency_ms;
  double tracker_p50 = 0, tracker_p99 = 0, mapper_p50 = 0, mapper_p99 = 0;
  double tracker_cpu_p50 = 0, tracker_cpu_p99 = 0;
  double wall_s = 0, mapper_total_ms = 0;
  ReplayReport rr;
  LatencyHistogram::Snapshot tracker_work, tracker_wait;

  if (single_thread) {
    const auto t0 = std::chrono::steady_clock::now();
    const OfflineRun run = run_offline(source, cfg.slam, camera);
    wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::vector<double> track_ms, mapper_ms, track_cpu_ms;
    for (const auto& f : run.frames) {
      states.push_back(f.result.state);
      track_ms.push_back(f.track_ms);
      track_cpu_ms.push_back(f.track_cpu_ms);
      // Offline latency: the frame is "published" when the tracker returns.
      latency_ms.push_back(f.track_ms);
      if (f.mapper_ms > 0) mapper_ms.push_back(f.mapper_ms);
      mapper_total_ms += f.mapper_ms;
    }
    tracker_p50 = percentile(track_ms, 0.5);
    tracker_p99 = percentile(track_ms, 0.99);
    tracker_cpu_p50 = percentile(track_cpu_ms, 0.5);
    tracker_cpu_p99 = percentile(track_cpu_ms, 0.99);
    mapper_p50 = percentile(mapper_ms, 0.5);
    mapper_p99 = percentile(mapper_ms, 0.99);
  } else {
    SlamStages stages = make_slam_stages(cfg.slam, camera);
    TimedTracker timed(*stages.tracker);
    PipelineOptions options;
    options.params = cfg.pipeline;
    options.threads = cfg.threads;
    options.lossless = true;
    rr = replay_source(source, timed, *stages.mapper, options);
    tracker_work = timed.work();
    tracker_wait = timed.wait();
    wall_s = rr.wall_s;
    for (const auto& f : rr.frames) {
      states.push_back(f.result.state);
      latency_ms.push_back(f.latency_ns() * 1e-6);
    }
    tracker_cpu_p50 = timed.cpu().percentile_ms(0.5);
    tracker_cpu_p99 = timed.cpu().percentile_ms(0.99);
    tracker_p50 = tracker_work.percentile_ms(0.5);
    tracker_p99 = tracker_work.percentile_ms(0.99);
    mapper_p50 = rr.stages.mapper.percentile_ms(0.5);
    mapper_p99 = rr.stages.mapper.percentile_ms(0.99);
    mapper_total_ms = rr.stages.mapper.mean_ms() * rr.stages.mapper.total;
  }
  compute_tracking_stats(states, report);
  compute_latency_stats(latency_ms, report);
  report.fps = wall_s > 0 ? states.size() / wall_s : 0.0;
  report.peak_rss_mb = peak_rss_mb();

  const char* mode = single_thread ? "single-thread" : "pipeline";
  if (json) {
    JsonWriter w;
    w.begin_object();
    report.write_json(w);
    w.value("source", uri);
    w.value("width", info.width);
    w.value("height", info.height);
    w.value("feature_mode", cfg.slam.features.mode);
    w.value("mode", mode);
    w.value("sync_mapper", cfg.slam.tracker.sync_mapper);
    w.value("preloaded", !no_preload);
    w.value("preload_mb", preload_mb);
    w.value("total_s", wall_s);
    w.value("ms_per_frame", states.empty() ? 0.0 : 1e3 * wall_s / states.size());
    w.begin_object("stages");
    write_stage(w, "tracker", tracker_p50, tracker_p99);
    write_stage(w, "tracker_cpu", tracker_cpu_p50, tracker_cpu_p99);
    write_stage(w, "mapper", mapper_p50, mapper_p99);
    if (!single_thread) {
      write_snapshot(w, "tracker_total", rr.stages.tracker);
      write_snapshot(w, "tracker_wait", tracker_wait);
      write_snapshot(w, "capture", rr.stages.capture_read);
      write_snapshot(w, "publish", rr.stages.publish);
    }
    w.end_object();
    w.value("mapper_total_ms", mapper_total_ms);
    if (!single_thread) {
      w.value("dropped", static_cast<int64_t>(rr.status.frames_dropped));
      w.value("publish_overflows", static_cast<int64_t>(rr.status.publish_overflows));
    }
    w.end_object();
    std::fputs(w.str().c_str(), stdout);
    return 0;
  }
  std::printf("rdslam bench pipeline %s (%dx%d, %s features, %s%s%s)\n", uri.c_str(), info.width,
              info.height, cfg.slam.features.mode.c_str(), mode,
              cfg.slam.tracker.sync_mapper ? ", tracker waits for keyframes" : "",
              preloaded ? ", frames preloaded" : "");
  std::printf("  %-22s %lld (tracked %.1f%%)\n", "frames", static_cast<long long>(report.frames),
              100.0 * report.tracked_ratio);
  std::printf("  %-22s %.3f s (%.2f ms per frame)\n", "total time", wall_s,
              states.empty() ? 0.0 : 1e3 * wall_s / states.size());
  std::printf("  %-22s %.1f\n", "fps", report.fps);
  print_stage("tracker", tracker_p50, tracker_p99,
              single_thread ? "per frame" : "per frame, without waits for the mapper");
  print_stage("tracker cpu", tracker_cpu_p50, tracker_cpu_p99,
              "tracker thread CPU time (robust to a loaded machine)");
  if (!single_thread) {
    print_stage("tracker total", rr.stages.tracker.percentile_ms(0.5),
                rr.stages.tracker.percentile_ms(0.99), "TrackerStage::track() incl. waits");
    print_stage("tracker wait", tracker_wait.percentile_ms(0.5), tracker_wait.percentile_ms(0.99),
                "per frame that waited for the mapper (sync)");
  }
  print_stage("mapper", mapper_p50, mapper_p99,
              single_thread ? "per frame that did mapper work" : "per step that did work");
  if (!single_thread) {
    print_stage("capture", rr.stages.capture_read.percentile_ms(0.5),
                rr.stages.capture_read.percentile_ms(0.99), "FrameSource::read()");
    print_stage("publish", rr.stages.publish.percentile_ms(0.5),
                rr.stages.publish.percentile_ms(0.99), "sinks");
  }
  print_stage("latency", report.latency_p50_ms, report.latency_p99_ms,
              single_thread ? "(= tracker time offline)" : "capture to publish");
  std::printf("  %-22s %.1f ms total\n", "mapper work", mapper_total_ms);
  std::printf("  %-22s %.1f MiB%s\n", "peak RSS", report.peak_rss_mb,
              preloaded ? " (includes the preloaded frames)" : "");
  if (preloaded) std::printf("  %-22s %.1f MiB\n", "preloaded frames", preload_mb);
  return 0;
}

}  // namespace rdslam
