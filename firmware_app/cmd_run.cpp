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
#include "firmware_app/lcm_publisher.h"
#include "firmware_app/passthrough_stages.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/service_notify.h"
#include "firmware_app/viewer_publisher.h"

namespace rdslam {

namespace {

// SIGINT/SIGTERM are blocked in every thread (threads inherit the mask from the thread that
// starts them) and taken synchronously by the supervising thread with sigtimedwait(): no
// asynchronous handler, nothing to make async-signal-safe.
class StopSignals {
 public:
  StopSignals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
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
  ArgParser p("rdslam run --config FILE [--set KEY=VALUE ...] [--log-level LEVEL]",
              "Run the SLAM daemon: read frames from the configured `source`, track them on the\n"
              "pipeline threads and publish rdslam.pose_t per frame and rdslam.status_t at 1 Hz\n"
              "over LCM, and the annotated image and map for rdslam view (viewer.*). A recorded\n"
              "source (e.g. --set source=tum:DIR) replays at pipeline.replay_speed and ends\n"
              "with exit code 0; a camera runs until SIGINT or\n"
              "SIGTERM. Logs go to stderr (journald-friendly).");
  p.config_options(&config_path, &overrides);
  p.option("--log-level", &log_level, "LEVEL", "debug, info, warn or error (sets log_level)");
  if (!p.parse(argc, argv)) return 0;
  if (!log_level.empty()) overrides.push_back("log_level=" + log_level);
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
  TrackerStage* tracker = nullptr;
  MapperStage* mapper = nullptr;
  CameraModel camera = cfg.camera;
  if (cfg.pipeline.stages == "passthrough") {
    passthrough = std::make_unique<PassthroughStages>(source->ground_truth());
    tracker = &passthrough->tracker();
    mapper = &passthrough->mapper();
  } else {
    if (!so.camera_overridden && source->camera()) camera = *source->camera();
    cfg.slam.parsac = cfg.parsac;
    slam = make_slam_stages(cfg.slam, camera);
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
  while (!pipeline.wait(0)) {
    const int sig = signals.wait(std::min(kSuperviseTickMs, notify.tick_period_ms()));
    notify.poll();
    if (sig != 0) {
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
  if (viewer) viewer->stop();
  const PipelineStatus s = pipeline.status();
  RDSLAM_LOG_INFO("run: %s after %llu frames (%llu dropped); %llu poses published",
                  pipeline.stop_requested() ? "stopped" : "end of stream",
                  static_cast<unsigned long long>(s.frames_processed),
                  static_cast<unsigned long long>(s.frames_dropped),
                  static_cast<unsigned long long>(lcm.poses_published()));
  return 0;
}

}  // namespace rdslam
