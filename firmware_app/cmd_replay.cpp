// `rdslam replay SOURCE`: the full threaded pipeline (capture, tracker, mapper, publisher
// threads; firmware_app/pipeline.h) with the SLAM stages (core/slam.h) on a recorded or
// synthetic source, as fast as possible (lossless) or in real time (--realtime). Prints a
// progress bar and a summary table; optionally writes the trajectory (TUM), the JSON report
// (the common keys of firmware_app/report.h plus SLAM keys) and a top-view plot, and a
// debug video / debug images of what the system decided (firmware_app/debug_video.h).
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>

#include "core/log.h"
#include "core/slam.h"
#include "core/trajectory_eval.h"
#include "drivers/decimated_source.h"
#include "drivers/fault_injection_source.h"
#include "drivers/loop_source.h"
#include "drivers/source_factory.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"
#include "firmware_app/debug_video.h"
#include "firmware_app/lcm_publisher.h"
#include "firmware_app/map_files.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/plot.h"
#include "firmware_app/progress.h"
#include "firmware_app/report.h"
#include "firmware_app/viewer_publisher.h"

namespace rdslam {

int cmd_replay(int argc, char** argv) {
  std::string uri, config_path, traj_path, report_path, plot_path, timings_path;
  std::string final_traj_path;
  std::vector<std::string> overrides;
  bool realtime = false;
  ArgParser p(
      "rdslam replay SOURCE [--config F] [--trajectory OUT.tum] [--report OUT.json] "
      "[--plot OUT.png] [--timings OUT.csv] [--realtime [--speed K] [--preload]] "
      "[--debug-video OUT.mp4] "
      "[--debug-images DIR] [--debug-every N] [--loop N] [--every N] [--map-log OUT.csv] "
      "[--lcm] [--inject SPEC] [--map FILE [--localize]] [--save-map FILE]",
      "Run the SLAM pipeline (all threads) on a recorded or synthetic source, e.g.\n"
      "synth:static_xyz or kitti:DIR, and print tracked %, fps, latency, map size and,\n"
      "when the source has ground truth, the ATE (Sim3-aligned).");
  p.positional("SOURCE", &uri, "frame source URI (synth:, tum:, euroc:, kitti:, images:, video:)");
  p.config_options(&config_path, &overrides);
  p.option("--trajectory", &traj_path, "OUT.tum", "write the tracked poses (TUM format)");
  p.option("--final-trajectory", &final_traj_path, "OUT.tum",
           "write the final trajectory: each tracked frame re-anchored on its reference "
           "keyframe's pose in the final map (TUM format; see ATE final)");
  p.option("--report", &report_path, "OUT.json", "write the JSON report");
  p.option("--plot", &plot_path, "OUT.png", "write a top-view plot against ground truth");
  p.option("--timings", &timings_path, "OUT.csv",
           "write per-frame timings (seq, index, state, queue+track ms, latency ms, track ms)");
  p.flag("--realtime", &realtime,
         "pace the source at its recorded rate and run the live pipeline: the tracker never "
         "waits for the mapper and takes the newest frame (drops possible)");
  // NaN: not given (the parser accepts finite numbers only).
  double speed = std::numeric_limits<double>::quiet_NaN();
  p.option("--speed", &speed, "K",
           "with --realtime: deliver frames at K times the recorded rate (K > 0, default 1; "
           "stamps unchanged), e.g. 3 to approximate a 3x slower board at camera rate");
  bool preload = false;
  p.flag("--preload", &preload,
         "with --realtime: read the whole source into memory before the replay starts (at most "
         "2 GiB, as --loop), so the capture thread only copies frames, as from a camera; "
         "without it, it decodes or renders each frame at the paced rate");
  double loops = 1;
  double every = 1;
  std::string map_log_path;
  p.option("--loop", &loops, "N",
           "play the source N times in a row (endurance run; the sequence is cached in memory "
           "at start, at most 2 GiB; at each restart the camera jumps back and must "
           "relocalize)");
  p.option("--every", &every, "N",
           "keep every N-th frame of a recorded source (frames 0, N, 2N, ...), stamps and "
           "ground truth unchanged: a fast-forward sequence, e.g. KITTI at 10/N Hz");
  p.option("--map-log", &map_log_path, "OUT.csv",
           "write the map size per frame (seq, state, keyframes, map points, points "
           "invalidated so far)");
  std::string inject_spec;
  p.option("--inject", &inject_spec, "SPEC",
           "damage frames to test fault tolerance: comma-separated KIND@FIRST[-LAST][:GAIN], "
           "frames numbered 0.. as the source (after --every, --loop) delivers them; KIND: "
           "corrupt, truncate (JPEG round trip through the MJPEG decoder), zero (0x0 image), "
           "black, saturated, exposure (pixels x GAIN), stamp_back, dup_stamp, drop, unplug "
           "(camera gone, then back); e.g. corrupt@40-45,drop@80-95,exposure@120-160:3 "
           "(docs/reliability.md)");
  std::string debug_video, debug_images;
  double debug_every = 1;
  p.option("--debug-video", &debug_video, "OUT.mp4",
           "write a video of what the tracker decided per frame: inliers (green), robust-"
           "estimator outliers (orange x), eq. (1) outliers (magenta x), map points (cyan), "
           "points invalidated in the last 30 frames (red), header with state and counts, top "
           "view; H.264 (avc1) or MPEG-4 (mp4v). Slows the replay (drawing and encoding on "
           "their own thread; lossless replay waits for them); poses are unchanged");
  p.option("--debug-images", &debug_images, "DIR",
           "write the same frames as DIR/frame_NNNNNN.png (DIR is created)");
  p.option("--debug-every", &debug_every, "N", "draw only every N-th frame (default 1)");
  // Ablation aliases of config keys (issue 8): the paper's Figures 9, 4-5 and 8.
  bool no_map_update = false, no_occlusion_handling = false;
  std::string estimator;
  p.flag("--no-map-update", &no_map_update, "alias of --set dynamic.map_update=false");
  p.flag("--no-occlusion-handling", &no_occlusion_handling,
         "alias of --set dynamic.occlusion_handling=false");
  p.option("--estimator", &estimator, "ransac|arsac|parsac", "alias of --set parsac.method=...");
  bool lcm_out = false;
  p.flag("--lcm", &lcm_out,
         "publish on the configured lcm.url what `rdslam run` publishes: rdslam.pose_t per "
         "frame, rdslam.status_t, the annotated JPEG image and rdslam.map_t (viewer.*), so a "
         "recording drives `rdslam view` and any LCM subscriber (not with --debug-video/-images)");
  // Saved maps (issue 24, core/map_io.h).
  std::string prior_map_path, save_map_path;
  bool localize = false;
  p.option("--map", &prior_map_path, "FILE",
           "start from a saved map (rdslam map info FILE shows it): the tracker relocalizes in "
           "it; without --localize the map keeps growing and updating");
  p.flag("--localize", &localize,
         "with --map: localization only, the map is frozen (no keyframes, no map updating)");
  p.option("--save-map", &save_map_path, "FILE",
           "write the map at the end of the replay (atomically: a temporary file, fsync, "
           "rename)");
  if (!p.parse(argc, argv)) return 0;
  if (lcm_out && (!debug_video.empty() || !debug_images.empty())) {
    throw UsageError(
        "--lcm: cannot be combined with --debug-video or --debug-images (the "
        "tracker has one debug output)");
  }
  if (no_map_update) overrides.push_back("dynamic.map_update=false");
  if (no_occlusion_handling) overrides.push_back("dynamic.occlusion_handling=false");
  if (!estimator.empty()) overrides.push_back("parsac.method=" + estimator);
  AppConfig cfg = load_cli_config(config_path, overrides);

  DebugVideoOptions dopt;
  const bool debug_out = !debug_video.empty() || !debug_images.empty();
  if (!debug_out && debug_every != 1) {
    throw UsageError("--debug-every: needs --debug-video or --debug-images");
  }
  if (debug_out) {
    if (debug_every < 1 || debug_every != std::floor(debug_every) || debug_every > 1e6) {
      throw UsageError("--debug-every: must be an integer >= 1");
    }
    dopt.video_path = debug_video;
    dopt.images_dir = debug_images;
    dopt.every = static_cast<int>(debug_every);
    dopt.lossless = !realtime;
    check_debug_output_paths(dopt);  // before the (possibly slow) source opens
  }

  if (!std::isnan(speed) && !realtime) {
    throw UsageError("--speed: needs --realtime (a lossless replay runs as fast as it can)");
  }
  if (preload && !realtime) throw UsageError("--preload: needs --realtime");
  if (localize && prior_map_path.empty()) throw UsageError("--localize: needs --map FILE");
  if (std::isnan(speed)) speed = 1.0;
  if (!(speed > 0.0) || speed > 1000.0) throw UsageError("--speed: must be in (0, 1000]");
  if (loops < 1 || loops != std::floor(loops) || loops > 1e6) {
    throw UsageError("--loop: must be an integer >= 1");
  }
  if (every < 1 || every != std::floor(every) || every > 1e6) {
    throw UsageError("--every: must be an integer >= 1");
  }
  std::vector<FaultSpan> faults;
  if (!inject_spec.empty()) {
    try {
      faults = parse_fault_spec(inject_spec);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  }
  // Opened before the run, so a bad path fails at once rather than after a long replay.
  std::unique_ptr<FILE, int (*)(FILE*)> map_log(nullptr, &std::fclose);
  if (!map_log_path.empty()) {
    map_log.reset(std::fopen(map_log_path.c_str(), "w"));
    if (!map_log) throw UsageError("--map-log: cannot write " + map_log_path);
  }
  const SourceOptions so = make_source_options(cfg, overrides, realtime ? speed : 0.0);
  std::unique_ptr<FrameSource> source;
  if (loops > 1 || preload) {
    SourceOptions unpaced = so;
    unpaced.speed = 0.0;  // the cache is filled as fast as the source reads
    try {
      source = make_looped_source(
          make_decimated_source(open_source(uri, unpaced), static_cast<int>(every)),
          static_cast<int>(loops), so.speed);
    } catch (const std::runtime_error& e) {
      if (loops > 1) throw;
      std::string m = e.what();  // the cache's messages name --loop
      if (m.rfind("--loop: ", 0) == 0) m = m.substr(8);
      throw std::runtime_error("--preload: " + m);
    }
  } else {
    source = make_decimated_source(open_source(uri, so), static_cast<int>(every));
  }
  source = make_fault_injection_source(std::move(source), std::move(faults));
  const CameraModel camera =
      (!so.camera_overridden && source->camera()) ? *source->camera() : cfg.camera;
  // Lossless replay maps like an offline run: the tracker waits for each keyframe.
  if (!realtime) cfg.slam.tracker.sync_mapper = true;
  cfg.slam.parsac = cfg.parsac;
  Map prior;
  MapInfo prior_info;
  SlamStart start;
  if (!prior_map_path.empty()) {
    prior = load_prior_map(prior_map_path, camera, cfg.slam.features, &prior_info);
    start.prior = &prior;
    start.localize_only = localize;
  }
  SlamStages stages = make_slam_stages(cfg.slam, camera, start);
  stages.mapper->set_keep_trail(true);  // the final trajectory (a replay is bounded)
  std::unique_ptr<DebugVideoWriter> debug_writer;
  if (debug_out) {
    dopt.fps = source->info().nominal_fps > 0 ? source->info().nominal_fps : 30.0;
    debug_writer = std::make_unique<DebugVideoWriter>(dopt, camera);
    stages.tracker->set_debug_sink(debug_writer.get());
  }
  std::unique_ptr<LcmPublisher> lcm_pub;
  std::unique_ptr<ViewerPublisher> viewer_pub;
  std::vector<PipelineSink*> sinks;
  if (lcm_out) {
    lcm_pub = std::make_unique<LcmPublisher>(cfg.lcm);
    sinks.push_back(lcm_pub.get());
    if (cfg.viewer.enabled()) {
      viewer_pub = std::make_unique<ViewerPublisher>(cfg.lcm, cfg.viewer, camera);
      stages.tracker->set_debug_sink(viewer_pub.get());
    }
  }

  PipelineOptions options;
  options.params = cfg.pipeline;
  options.threads = cfg.threads;
  options.lossless = !realtime;
  ProgressSink progress(source->info().frame_count, stderr);
  sinks.push_back(&progress);
  const ReplayReport rr = replay_source(*source, *stages.tracker, *stages.mapper, options, sinks);
  if (viewer_pub) viewer_pub->stop();
  DebugVideoStats dstats;
  if (debug_writer) dstats = debug_writer->finish();
  // The mapper thread has stopped: the map is saved from this thread.
  std::string map_saved;
  if (!save_map_path.empty() && !stages.mapper->save_map(save_map_path, 1, &map_saved)) {
    throw std::runtime_error("--save-map " + save_map_path + ": " + map_saved);
  }

  RunReport report;
  std::vector<TrackingState> states;
  std::vector<double> latency_ms, track_ms;
  for (const auto& f : rr.frames) {
    states.push_back(f.result.state);
    latency_ms.push_back(f.latency_ns() * 1e-6);
    track_ms.push_back(f.track_ns * 1e-6);
  }
  const Trajectory est = replay_trajectory(rr);
  const Trajectory final_est = replay_trajectory(rr, stages.mapper.get());
  compute_tracking_stats(states, report);
  compute_latency_stats(latency_ms, report);
  const StateTiming init_ms = tracker_ms_in_state(states, track_ms, TrackingState::kInitializing);
  const StateTiming lost_ms = tracker_ms_while_lost(states, track_ms);
  report.fps = rr.wall_s > 0 ? rr.frames.size() / rr.wall_s : 0.0;
  report.peak_rss_mb = peak_rss_mb();
  const std::optional<Trajectory> gt = source->ground_truth();
  std::string ate_note = "no ground truth";
  RunReport final_report;  // only its ATE fields: the final trajectory's
  if (gt && !gt->empty()) {
    ate_note = compute_ate(*gt, est, report);
    compute_ate(*gt, final_est, final_report);
  }
  const int map_points = rr.frames.empty() ? 0 : rr.frames.back().result.map_points;
  const int keyframes = rr.frames.empty() ? 0 : rr.frames.back().result.keyframes;
  std::set<uint32_t> epochs;  // of the tracked frames (recovery: new maps)
  for (const auto& f : rr.frames) {
    if (f.result.state == TrackingState::kTracking ||
        f.result.state == TrackingState::kRelocalized) {
      epochs.insert(f.result.epoch);
    }
  }
  const size_t map_epochs = epochs.size();
  const int map_merges = rr.frames.empty() ? 0 : rr.frames.back().result.map_merges;

  std::printf("\nrdslam replay %s (%s features)\n", uri.c_str(), cfg.slam.features.mode.c_str());
  std::printf("  %-26s %lld\n", "frames", static_cast<long long>(report.frames));
  std::printf("  %-26s %lld (%.1f%%; %.1f%% after init at frame %lld)\n", "tracked",
              static_cast<long long>(report.tracked_frames), 100.0 * report.tracked_ratio,
              100.0 * report.tracked_ratio_after_init,
              static_cast<long long>(report.initialized_frame));
  std::printf("  %-26s %.1f\n", "fps", report.fps);
  std::printf("  %-26s p50 %.2f  p99 %.2f\n", "tracker ms", rr.stages.tracker.percentile_ms(0.5),
              rr.stages.tracker.percentile_ms(0.99));
  if (init_ms.frames > 0) {
    std::printf("  %-26s p50 %.2f  p99 %.2f (%lld frames)\n", "tracker ms initializing",
                *init_ms.p50_ms, *init_ms.p99_ms, static_cast<long long>(init_ms.frames));
  }
  if (lost_ms.frames > 0) {
    std::printf("  %-26s p50 %.2f  p99 %.2f (%lld frames)\n", "tracker ms lost", *lost_ms.p50_ms,
                *lost_ms.p99_ms, static_cast<long long>(lost_ms.frames));
  }
  std::printf("  %-26s p50 %.2f  p99 %.2f\n", "latency ms", report.latency_p50_ms,
              report.latency_p99_ms);
  const PipelineStatus& st = rr.status;
  std::printf("  %-26s %llu (source skipped %llu, capture %llu, tracker %llu)\n", "dropped",
              static_cast<unsigned long long>(st.frames_dropped),
              static_cast<unsigned long long>(st.source_skipped),
              static_cast<unsigned long long>(st.dropped_capture),
              static_cast<unsigned long long>(st.dropped_tracker));
  if (st.source_faults + st.source_timeouts + st.frames_invalid + st.stamps_rejected +
          st.frames_blank + st.exposure_jumps >
      0) {
    std::printf(
        "  %-26s %llu faults, %llu timeouts, %llu reopens, rejected %llu invalid + %llu "
        "stamps, %llu blank, %llu exposure jumps\n",
        "source", static_cast<unsigned long long>(st.source_faults),
        static_cast<unsigned long long>(st.source_timeouts),
        static_cast<unsigned long long>(st.source_reopens),
        static_cast<unsigned long long>(st.frames_invalid),
        static_cast<unsigned long long>(st.stamps_rejected),
        static_cast<unsigned long long>(st.frames_blank),
        static_cast<unsigned long long>(st.exposure_jumps));
  }
  std::printf("  %-26s %d points, %d keyframes\n", "map", map_points, keyframes);
  if (realtime && !stages.mapper->summary().empty()) {
    std::printf("  %-26s %s\n", "mapper", stages.mapper->summary().c_str());
  }
  if (map_epochs > 1 || map_merges > 0) {
    std::printf("  %-26s %zu epochs, %d merges\n", "maps", map_epochs, map_merges);
  }
  int64_t first_pose = -1;  // first TRACKING or RELOCALIZED frame
  for (size_t i = 0; i < states.size() && first_pose < 0; ++i) {
    if (states[i] == TrackingState::kTracking || states[i] == TrackingState::kRelocalized) {
      first_pose = static_cast<int64_t>(i);
    }
  }
  if (!prior_map_path.empty()) {
    std::printf("  %-26s %s (%d keyframes, %d points; %s), first pose at frame %lld\n", "prior map",
                prior_map_path.c_str(), prior_info.keyframes, prior_info.points,
                localize ? "localization only" : "mapping continues",
                static_cast<long long>(first_pose));
  }
  if (!save_map_path.empty()) {
    std::printf("  %-26s %s (%s)\n", "map saved", save_map_path.c_str(), map_saved.c_str());
  }
  if (report.ate_rmse_m) {
    std::printf("  %-26s %.4f m (%.3f%% of path)\n", "ATE rmse (Sim3)", *report.ate_rmse_m,
                report.ate_rmse_pct_path.value_or(0.0));
  } else {
    std::printf("  %-26s n/a (%s)\n", "ATE rmse (Sim3)", ate_note.c_str());
  }
  if (final_report.ate_rmse_m) {
    std::printf("  %-26s %.4f m (%.3f%% of path)\n", "ATE final (Sim3)", *final_report.ate_rmse_m,
                final_report.ate_rmse_pct_path.value_or(0.0));
  }
  std::printf("  %-26s %.1f MiB\n", "peak RSS", report.peak_rss_mb);
  if (debug_writer) {
    std::printf("  %-26s %lld of %lld frames drawn", "debug output",
                static_cast<long long>(dstats.drawn), static_cast<long long>(dstats.received));
    if (!debug_video.empty()) {
      std::printf(", %s (%s)", debug_video.c_str(), dstats.codec.c_str());
    }
    if (!debug_images.empty()) {
      std::printf(", %lld PNGs in %s", static_cast<long long>(dstats.images), debug_images.c_str());
    }
    if (dstats.dropped > 0) std::printf(", %lld dropped", static_cast<long long>(dstats.dropped));
    std::printf("\n");
  }
  if (lcm_pub) {
    std::printf("  %-26s %llu poses, %llu statuses on %s", "lcm",
                static_cast<unsigned long long>(lcm_pub->poses_published()),
                static_cast<unsigned long long>(lcm_pub->statuses_published()),
                cfg.lcm.url.c_str());
    if (viewer_pub) {
      const ViewerPublisherStats vs = viewer_pub->stats();
      std::printf("; viewer: %llu images (largest %llu B), %llu maps (largest %llu B)",
                  static_cast<unsigned long long>(vs.images),
                  static_cast<unsigned long long>(vs.max_image_bytes),
                  static_cast<unsigned long long>(vs.maps),
                  static_cast<unsigned long long>(vs.max_map_bytes));
    }
    std::printf("\n");
  }

  if (!traj_path.empty()) write_trajectory_tum(traj_path, est);
  if (!final_traj_path.empty()) write_trajectory_tum(final_traj_path, final_est);
  if (!timings_path.empty()) {
    // Capture-to-publish latency of every published frame, split at track() return.
    FILE* f = std::fopen(timings_path.c_str(), "w");
    if (!f) throw std::runtime_error("cannot write " + timings_path);
    std::fprintf(f, "seq,dataset_index,state,arrival_to_tracked_ms,latency_ms,track_ms\n");
    for (const auto& fr : rr.frames) {
      std::fprintf(f, "%llu,%lld,%s,%.3f,%.3f,%.3f\n", static_cast<unsigned long long>(fr.seq),
                   static_cast<long long>(fr.dataset_index), to_string(fr.result.state),
                   (fr.tracked_mono_ns - fr.arrival_mono_ns) * 1e-6, fr.latency_ns() * 1e-6,
                   fr.track_ns * 1e-6);
    }
    std::fclose(f);
  }
  if (map_log) {
    FILE* f = map_log.get();
    std::fprintf(f, "seq,dataset_index,state,keyframes,map_points,invalidated_points\n");
    for (const auto& fr : rr.frames) {
      std::fprintf(f, "%llu,%lld,%s,%d,%d,%lld\n", static_cast<unsigned long long>(fr.seq),
                   static_cast<long long>(fr.dataset_index), to_string(fr.result.state),
                   fr.result.keyframes, fr.result.map_points,
                   static_cast<long long>(fr.result.invalidated_points));
    }
    if (std::fflush(f) != 0) throw std::runtime_error("--map-log: write error on " + map_log_path);
  }
  if (!report_path.empty()) {
    JsonWriter w;
    w.begin_object();
    report.write_json(w);
    w.begin_object("ate_final");  // the final trajectory (--final-trajectory)
    w.value("rmse_m", final_report.ate_rmse_m);
    w.value("rmse_pct_path", final_report.ate_rmse_pct_path);
    w.end_object();
    w.value("source", uri);
    w.value("realtime", realtime);
    // Pacing: K x the recorded rate (--realtime --speed K); 0 = lossless (as fast as possible).
    w.value("speed", realtime ? speed : 0.0);
    w.value("wall_s", rr.wall_s);  // the pipeline's run, start to join
    w.value("feature_mode", cfg.slam.features.mode);
    w.value("map_points", map_points);
    w.value("keyframes", keyframes);
    w.value("invalidated_points",
            rr.frames.empty() ? int64_t{0} : rr.frames.back().result.invalidated_points);
    w.begin_object("tracker_ms");
    w.value("p50", rr.stages.tracker.percentile_ms(0.5));
    w.value("p99", rr.stages.tracker.percentile_ms(0.99));
    w.end_object();
    // Frames processed while INITIALIZING (before the map exists); null when there were none.
    w.begin_object("init_tracker_ms");
    w.value("p50", init_ms.p50_ms);
    w.value("p99", init_ms.p99_ms);
    w.value("frames", init_ms.frames);
    w.end_object();
    // Frames processed while LOST (relocalization; tracker_ms_while_lost); null when none.
    w.begin_object("lost_tracker_ms");
    w.value("p50", lost_ms.p50_ms);
    w.value("p99", lost_ms.p99_ms);
    w.value("frames", lost_ms.frames);
    w.end_object();
    w.begin_object("dropped");  // captured + source_skipped == processed + total
    w.value("total", static_cast<int64_t>(st.frames_dropped));
    w.value("source_skipped", static_cast<int64_t>(st.source_skipped));
    w.value("capture", static_cast<int64_t>(st.dropped_capture));
    w.value("tracker", static_cast<int64_t>(st.dropped_tracker));
    w.value("publish_overflows", static_cast<int64_t>(st.publish_overflows));
    w.end_object();
    // Recovery (docs/slam.md): map epochs the tracked frames were in, and merges of a newer map
    // into an earlier one.
    w.value("map_epochs", static_cast<int64_t>(map_epochs));
    w.value("map_merges", static_cast<int64_t>(map_merges));
    w.begin_object("source_faults");  // rdslam.status_t's fault counters (docs/reliability.md)
    w.value("faults", static_cast<int64_t>(st.source_faults));
    w.value("timeouts", static_cast<int64_t>(st.source_timeouts));
    w.value("reopens", static_cast<int64_t>(st.source_reopens));
    w.value("frames_invalid", static_cast<int64_t>(st.frames_invalid));
    w.value("stamps_rejected", static_cast<int64_t>(st.stamps_rejected));
    w.value("frames_blank", static_cast<int64_t>(st.frames_blank));
    w.value("exposure_jumps", static_cast<int64_t>(st.exposure_jumps));
    w.end_object();
    // Saved maps (--map, --localize, --save-map); first_pose_frame: the first TRACKING or
    // RELOCALIZED frame (-1: none).
    w.begin_object("prior_map");
    w.value("file", prior_map_path);
    w.value("localize_only", localize);
    w.value("keyframes", prior_info.keyframes);
    w.value("points", prior_info.points);
    w.value("first_pose_frame", first_pose);
    w.value("saved_to", save_map_path);
    w.end_object();
    w.end_object();
    FILE* f = std::fopen(report_path.c_str(), "w");
    if (!f) throw std::runtime_error("cannot write " + report_path);
    const std::string doc = w.str();
    std::fwrite(doc.data(), 1, doc.size(), f);
    std::fclose(f);
  }
  if (!plot_path.empty()) {
    TrajectoryPlot plot;
    plot.title = "rdslam replay " + uri;
    if (gt && !gt->empty() && est.size() >= 3) {
      EvalParams ep;
      const EvalResult er = evaluate_trajectories(*gt, est, ep);
      if (er.ok) {
        plot.tracks.push_back({"ground truth", cv::Scalar(0, 0, 0), er.gt_positions, 2});
        plot.tracks.push_back(
            {"rdslam (Sim3-aligned)", cv::Scalar(0, 0, 255), er.est_positions_aligned, 2});
      }
    }
    if (plot.tracks.empty()) {
      std::vector<Eigen::Vector3d> pts;
      for (const auto& sp : est) pts.push_back(sp.p_world_cam);
      plot.tracks.push_back({"rdslam", cv::Scalar(0, 0, 255), pts, 2});
    }
    write_trajectory_plot(plot, plot_path);
  }
  if (!dstats.error.empty()) throw std::runtime_error("debug output: " + dstats.error);
  return 0;
}

}  // namespace rdslam
