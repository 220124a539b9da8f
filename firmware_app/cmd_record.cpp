// `rdslam record --source URI --out DIR [--seconds N]`: records any frame source into a
// TUM-format folder (drivers/recorder.h) that `replay` reads back bit-identically.
#include <signal.h>
#include <time.h>

#include <cstdio>
#include <memory>

#include "core/log.h"
#include "drivers/recorder.h"
#include "drivers/source_factory.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace rdslam {

namespace {

// SIGINT/SIGTERM are blocked and polled between frames, so no read or write is ever
// interrupted half-way: the frame in progress is finished, then the folder is closed.
class BlockedStopSignals {
 public:
  BlockedStopSignals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set_, &old_);
  }
  ~BlockedStopSignals() { pthread_sigmask(SIG_SETMASK, &old_, nullptr); }
  // The pending stop signal, or 0 (does not wait).
  int poll() {
    const timespec zero{0, 0};
    const int sig = sigtimedwait(&set_, nullptr, &zero);
    return sig > 0 ? sig : 0;
  }

 private:
  sigset_t set_{}, old_{};
};

// Read timeout of one poll: bounds how long a stop signal waits on a silent live source.
constexpr int kReadTimeoutMs = 100;

}  // namespace

int cmd_record(int argc, char** argv) {
  std::string config_path, source_uri, out_dir;
  std::vector<std::string> overrides;
  double seconds = 0.0;
  double speed = 0.0;
  ArgParser p(
      "rdslam record --source URI --out DIR [--seconds N] [--speed X] [--config FILE] "
      "[--set KEY=VALUE ...]",
      "Record frames from a source into a TUM RGB-D folder: DIR/rgb/<stamp>.png (lossless),\n"
      "DIR/rgb.txt with exact timestamps and DIR/camera.yaml. `rdslam replay` (or any\n"
      "tum:DIR source) reads it back bit-identically. Refuses to write into an existing\n"
      "non-empty DIR. SIGINT/SIGTERM stop cleanly: everything written so far stays intact.");
  p.config_options(&config_path, &overrides);
  p.option("--source", &source_uri, "URI", "frame source (default: the config's source)");
  p.option("--out", &out_dir, "DIR", "output folder (must not exist or be empty)");
  p.option("--seconds", &seconds, "N", "stop after N seconds (default: until the source ends)");
  p.option("--speed", &speed, "X",
           "recorded sources: 0 = as fast as possible (default), X = real time scaled by X");
  if (!p.parse(argc, argv)) return 0;
  if (out_dir.empty()) throw UsageError("--out DIR is required");
  if (seconds < 0.0) throw UsageError("--seconds must be >= 0");
  if (speed < 0.0) throw UsageError("--speed must be >= 0");
  AppConfig cfg = load_cli_config(config_path, overrides);
  if (source_uri.empty()) source_uri = cfg.general.source;

  BlockedStopSignals signals;  // before anything that might start a thread
  const SourceOptions so = make_source_options(cfg, overrides, speed);
  std::unique_ptr<FrameSource> source = open_source(source_uri, so);
  TumRecorder recorder(out_dir, source_uri, source->camera());

  const SourceInfo& info = source->info();
  Frame frame;
  frame.image.create(info.height > 0 ? info.height : 1, info.width > 0 ? info.width : 1,
                     info.format == PixelFormat::kGray8 ? CV_8UC1 : CV_8UC3);
  const int64_t start = mono_now_ns();
  const int64_t limit_ns = static_cast<int64_t>(seconds * 1e9);
  const char* why = "end of stream";
  int exit_code = 0;
  for (;;) {
    if (const int sig = signals.poll()) {
      why = sig == SIGINT ? "SIGINT" : "SIGTERM";
      break;
    }
    if (limit_ns > 0 && mono_now_ns() - start >= limit_ns) {
      why = "--seconds reached";
      break;
    }
    const SourceStatus st = source->read(frame, kReadTimeoutMs);
    if (st == SourceStatus::kEndOfStream) break;
    if (st != SourceStatus::kOk) continue;  // timeout or fault: counted by the source
    if (!recorder.write(frame) && recorder.failures() == 1) {
      RDSLAM_LOG_ERROR("record: cannot write frame %llu into %s (disk full?)",
                       static_cast<unsigned long long>(frame.seq), out_dir.c_str());
    }
  }
  recorder.close();
  const SourceCounters c = source->counters();
  if (recorder.failures() > 0) exit_code = 1;
  std::printf(
      "record: %s: %llu frames (%.1f MB) in %s in %.1f s; source: %llu delivered, "
      "%llu faults, %llu skipped, %llu timeouts; %llu write failures\n",
      why, static_cast<unsigned long long>(recorder.written()),
      static_cast<double>(recorder.bytes()) / 1e6, out_dir.c_str(),
      static_cast<double>(mono_now_ns() - start) / 1e9,
      static_cast<unsigned long long>(c.delivered), static_cast<unsigned long long>(c.faults),
      static_cast<unsigned long long>(c.skipped), static_cast<unsigned long long>(c.timeouts),
      static_cast<unsigned long long>(recorder.failures()));
  return exit_code;
}

}  // namespace rdslam
