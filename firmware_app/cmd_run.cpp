// `rdslam run`: the daemon. Opens the configured source, builds the stages (pass-through
// until the SLAM core lands), publishes over LCM and supervises the pipeline until the
// source ends (exit 0) or SIGINT/SIGTERM arrives (clean stop within 2 s, exit 0).
#include <signal.h>

#include <algorithm>
#include <cerrno>
#include <ctime>
#include <memory>

#include "core/log.h"
#include "core/slam.h"
#include "drivers/source_factory.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"
#include "firmware_app/lcm_commands.h"
#include "firmware_app/lcm_publisher.h"
#include "firmware_app/map_files.h"
#include "firmware_app/map_writer.h"
#include "firmware_app/passthrough_stages.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/service_notify.h"
#include "firmware_app/viewer_publisher.h"

namespace rdslam {

namespace {

// SIGINT/SIGTERM (stop) and SIGUSR1 (save the map) are blocked in every thread (threads inherit the
// mask from the thread that starts them) and taken synchronously by the supervising thread with
// sigtimedwait(): no asynchronous handler, nothing to make async-signal-safe.
class StopSignals {
 public:
  StopSignals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    sigaddset(&set_, SIGUSR1);
    pthread_sigmask(SIG_BLOCK, &set_, &old_);
  }
  ~StopSignals() { pthread_sigmask(SIG_SETMASK, &old_, nullptr); }
  // The signal number received within `timeout_ms`, or 0.
  int wait(int timeout_ms) {
    timespec ts{timeout_ms / 1000, static_cast<long>(timeout_ms % 1000) * 1000000L};
    const int sig = sigtimedwait(&set_, nullptr, &ts);
    return sig > 0 ? sig : 0;
  }

 private:
  sigset_t set_{}, old_{};
};

// Supervision period: how often the loop below looks at the pipeline.
constexpr int kSuperviseTickMs = 100;

}  // namespace

int cmd_run(int argc, char** argv) {
  std::string config_path, log_level;
  std::vector<std::string> overrides;
  ArgParser p(
      "rdslam run --config FILE [--set KEY=VALUE ...] [--log-level LEVEL] "
      "[--map FILE [--localize]] [--save-map FILE]",
      "Run the SLAM daemon: read frames from the configured `source`, track them on the\n"
      "pipeline threads and publish rdslam.pose_t per frame and rdslam.status_t at 1 Hz\n"
      "over LCM, and the annotated image and map for rdslam view (viewer.*). A recorded\n"
      "source (e.g. --set source=tum:DIR) replays at pipeline.replay_speed and ends\n"
      "with exit code 0; a camera runs until SIGINT or\n"
      "SIGTERM. Logs go to stderr (journald-friendly). SIGUSR1 saves the map to\n"
      "map.save_path; rdslam.command_t on lcm.command_channel resets the map, saves it or\n"
      "switches between localization and mapping (LCM has no authentication).");
  p.config_options(&config_path, &overrides);
  p.option("--log-level", &log_level, "LEVEL", "debug, info, warn or error (sets log_level)");
  // Saved maps (issue 24, core/map_io.h, config section `map`).
  std::string prior_map_path, save_map_path;
  bool localize = false;
  p.option("--map", &prior_map_path, "FILE",
           "start from a saved map: the tracker relocalizes in it; without --localize the map "
           "keeps growing and updating");
  p.flag("--localize", &localize, "with --map: localization only, the map is frozen");
  p.option("--save-map", &save_map_path, "FILE",
           "save the map to FILE (sets map.save_path): at the end of the run "
           "(map.save_on_shutdown), every map.save_period_s seconds and on SIGUSR1");
  if (!p.parse(argc, argv)) return 0;
  if (!log_level.empty()) overrides.push_back("log_level=" + log_level);
  if (localize && prior_map_path.empty()) throw UsageError("--localize: needs --map FILE");
  if (!save_map_path.empty()) overrides.push_back("map.save_path=" + save_map_path);
  AppConfig cfg = load_cli_config(config_path, overrides);
  for (const auto& kv : non_default_params(cfg)) RDSLAM_LOG_INFO("config: %s", kv.c_str());

  // Before any thread exists (LCM, pipeline), so that every thread inherits the mask.
  StopSignals signals;

  const SourceOptions so = make_source_options(cfg, overrides, cfg.pipeline.replay_speed);
  std::unique_ptr<FrameSource> source = open_source(cfg.general.source, so);
  const SourceInfo& info = source->info();
  RDSLAM_LOG_INFO("run: source %s (%s, %dx%d, %s, %.1f fps nominal)", info.uri.c_str(),
                  info.kind.c_str(), info.width, info.height, info.live ? "live" : "recorded",
                  info.nominal_fps);

  // The SLAM system, or the pass-through stages (ground truth) for testing consumers.
  std::unique_ptr<PassthroughStages> passthrough;
  SlamStages slam;
  std::unique_ptr<MapWriter> map_writer;  // saves while running (firmware_app/map_writer.h)
  TrackerStage* tracker = nullptr;
  MapperStage* mapper = nullptr;
  if (cfg.pipeline.stages == "passthrough" && !prior_map_path.empty()) {
    throw UsageError("--map: needs pipeline.stages=slam (the pass-through stages have no map)");
  }
  Map prior;
  CameraModel camera = cfg.camera;
  if (cfg.pipeline.stages == "passthrough") {
    passthrough = std::make_unique<PassthroughStages>(source->ground_truth());
    tracker = &passthrough->tracker();
    mapper = &passthrough->mapper();
  } else {
    if (!so.camera_overridden && source->camera()) camera = *source->camera();
    cfg.slam.parsac = cfg.parsac;
    SlamStart start;
    start.save_path = cfg.map.save_path;
    start.save_keep = cfg.map.keep;
    if (!cfg.map.save_path.empty()) {
      map_writer = std::make_unique<MapWriter>(cfg.threads.mapper.cores, cfg.map.writer_nice);
      start.save_writer = map_writer.get();
    }
    if (!prior_map_path.empty()) {
      MapInfo mi;
      prior = load_prior_map(prior_map_path, camera, cfg.slam.features, &mi);
      start.prior = &prior;
      start.localize_only = localize;
      RDSLAM_LOG_INFO("run: map %s loaded (%d keyframes, %d points); %s", prior_map_path.c_str(),
                      mi.keyframes, mi.points,
                      localize ? "localization only" : "mapping continues");
    }
    slam = make_slam_stages(cfg.slam, camera, start);
    tracker = slam.tracker.get();
    mapper = slam.mapper.get();
  }
  RDSLAM_LOG_INFO("run: stages %s", cfg.pipeline.stages.c_str());
  LcmPublisher lcm(cfg.lcm);
  // The viewer's image and map (viewer.*), from the tracker's debug records on a thread of
  // their own; the pass-through stages have no debug output.
  std::unique_ptr<ViewerPublisher> viewer;
  if (cfg.viewer.enabled() && cfg.pipeline.stages != "passthrough") {
    viewer = std::make_unique<ViewerPublisher>(cfg.lcm, cfg.viewer, camera);
    tracker->set_debug_sink(viewer.get());
    RDSLAM_LOG_INFO("run: viewer image on %s at %g Hz, map on %s at %g Hz",
                    cfg.lcm.image_channel.c_str(), cfg.viewer.image_hz, cfg.lcm.map_channel.c_str(),
                    cfg.viewer.map_hz);
  }
  PipelineOptions options;
  options.params = cfg.pipeline;
  options.threads = cfg.threads;
  options.lossless = !info.live && cfg.pipeline.replay_speed == 0.0;
  Pipeline pipeline(*source, *tracker, *mapper, options);
  pipeline.add_sink(&lcm);
  pipeline.start();
  RDSLAM_LOG_INFO("run: publishing %s on %s, status on %s", cfg.lcm.pose_channel.c_str(),
                  cfg.lcm.url.c_str(), cfg.lcm.status_channel.c_str());

  // Supervision loop. Observer hooks for supervisors (sd_notify, issue 11):
  // pipeline.frames_captured() / frames_processed() (progress), pipeline.status() (state,
  // fps, drops; refreshed every stats period), pipeline.running().
  PipelineNotifier notify(pipeline);  // systemd READY/STATUS/WATCHDOG/STOPPING (issue 11)
  // Map saves while running (the mapper thread serves the requests, core/keyframe.h).
  const bool can_save = slam.link && !cfg.map.save_path.empty();
  const int64_t save_period_ns = static_cast<int64_t>(cfg.map.save_period_s * 1e9);
  int64_t next_save_ns = mono_now_ns() + save_period_ns;
  // Commands over LCM (firmware_app/lcm_commands.h), handled on this thread.
  std::unique_ptr<LcmCommands> commands;
  if (slam.link && !cfg.lcm.command_channel.empty()) {
    commands =
        std::make_unique<LcmCommands>(cfg.lcm.url, cfg.lcm.command_channel, slam.link, can_save);
    RDSLAM_LOG_INFO("run: commands (rdslam.command_t) on %s", cfg.lcm.command_channel.c_str());
  }
  while (!pipeline.wait(0)) {
    const int sig = signals.wait(std::min(kSuperviseTickMs, notify.tick_period_ms()));
    notify.poll();
    if (commands) commands->poll();
    if (can_save && save_period_ns > 0 && mono_now_ns() >= next_save_ns) {
      slam.link->save_requests.fetch_add(1);
      next_save_ns += save_period_ns;
    }
    if (sig == SIGUSR1) {
      if (can_save) {
        RDSLAM_LOG_INFO("run: SIGUSR1 received, saving the map to %s", cfg.map.save_path.c_str());
        slam.link->save_requests.fetch_add(1);
      } else {
        RDSLAM_LOG_WARN("run: SIGUSR1 received, but no map file is configured (map.save_path)");
      }
    } else if (sig != 0) {
      if (!pipeline.stop_requested()) {
        RDSLAM_LOG_INFO("run: %s received, stopping", sig == SIGINT ? "SIGINT" : "SIGTERM");
        notify.stopping(sig == SIGINT ? "SIGINT" : "SIGTERM");
        pipeline.request_stop();
      } else {
        RDSLAM_LOG_INFO("run: already stopping");
      }
    }
  }
  notify.stopping("end of stream");  // no-op after a signal
  pipeline.join();
  if (map_writer) map_writer->stop();  // a save in progress is finished before the last one
  if (viewer) viewer->stop();
  const PipelineStatus s = pipeline.status();
  RDSLAM_LOG_INFO("run: %s after %llu frames (%llu dropped); %llu poses published",
                  pipeline.stop_requested() ? "stopped" : "end of stream",
                  static_cast<unsigned long long>(s.frames_processed),
                  static_cast<unsigned long long>(s.frames_dropped),
                  static_cast<unsigned long long>(lcm.poses_published()));
  if (commands) {
    RDSLAM_LOG_INFO("run: commands: %llu accepted, %llu rejected, %llu malformed",
                    static_cast<unsigned long long>(commands->accepted()),
                    static_cast<unsigned long long>(commands->rejected()),
                    static_cast<unsigned long long>(commands->malformed()));
  }
  if (can_save) {
    // Requests still waiting for the writer when the pipeline stopped: the final save (or
    // none, without map.save_on_shutdown) is the last word on them.
    const SlamLink& l = *slam.link;
    const uint32_t served = l.saves_done + l.saves_failed + l.saves_coalesced;
    RDSLAM_LOG_INFO(
        "run: map saves while running: %u requested, %u written, %u failed, %u coalesced, %u "
        "pending at the end",
        l.save_requests.load(), l.saves_done.load(), l.saves_failed.load(),
        l.saves_coalesced.load(), l.save_requests - std::min(l.save_requests.load(), served));
  }
  if (can_save && cfg.map.save_on_shutdown) {
    // Every thread has stopped: the map is saved from this thread.
    std::string msg;
    if (!mapper->save_map(cfg.map.save_path, cfg.map.keep, &msg)) {
      RDSLAM_LOG_ERROR("run: map not saved to %s: %s", cfg.map.save_path.c_str(), msg.c_str());
      return 1;
    }
    RDSLAM_LOG_INFO("run: map saved to %s (%s)", cfg.map.save_path.c_str(), msg.c_str());
  }
  return 0;
}

}  // namespace rdslam
