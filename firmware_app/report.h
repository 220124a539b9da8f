// The summary every `rdslam` subcommand that processes frames prints with --json (issue 3):
// the common keys `frames`, `tracked_frames`, `tracked_ratio`, `initialized_frame`,
// `tracked_ratio_after_init`, `ate_rmse_m`, `ate_rmse_pct_path`, `fps`, `latency_ms`
// {`p50`, `p99`}, `peak_rss_mb`, plus a small JSON writer so that subcommands add their own
// keys in the same style.
//
// Ownership: values. Threads: the thread that prints the report (main), after the run; the
// helpers allocate and must not be called per frame.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/stages.h"
#include "core/trajectory.h"

namespace rdslam {

// Streaming JSON writer with two-space indentation. Keys and string values are escaped;
// non-finite numbers and empty optionals are written as null.
class JsonWriter {
 public:
  JsonWriter();
  // Opens an object: the root when `key` is null (must be the first call), else a member.
  JsonWriter& begin_object(const char* key = nullptr);
  JsonWriter& end_object();
  JsonWriter& begin_array(const char* key);
  JsonWriter& end_array();
  JsonWriter& value(const char* key, double v);
  JsonWriter& value(const char* key, int64_t v);
  JsonWriter& value(const char* key, int v) { return value(key, static_cast<int64_t>(v)); }
  JsonWriter& value(const char* key, size_t v) { return value(key, static_cast<int64_t>(v)); }
  JsonWriter& value(const char* key, bool v);
  JsonWriter& value(const char* key, const std::string& v);
  JsonWriter& value(const char* key, const char* v) { return value(key, std::string(v)); }
  JsonWriter& value(const char* key, const std::optional<double>& v);
  JsonWriter& null(const char* key);
  // Array elements (inside begin_array/end_array).
  JsonWriter& element(double v);
  // The document; call after the root object is closed. Ends with a newline.
  std::string str() const;

 private:
  void open_item(const char* key);
  JsonWriter& close(char bracket);
  std::string out_;
  std::vector<bool> first_;  // per open container: no member written yet
};

// Quantile q in [0, 1] of `values` with linear interpolation between order statistics
// (numpy.percentile's default). 0 for an empty input. Takes a copy: it sorts.
double percentile(std::vector<double> values, double q);

// Peak resident set size of this process in MiB (VmHWM from /proc/self/status; getrusage's
// ru_maxrss as a fallback). 0 if neither is available.
double peak_rss_mb();

struct RunReport {
  int64_t frames = 0;
  int64_t tracked_frames = 0;               // frames in TRACKING or RELOCALIZED (a supported pose)
  double tracked_ratio = 0.0;               // tracked_frames / frames
  int64_t initialized_frame = -1;           // index of the first TRACKING frame, -1 if never
  double tracked_ratio_after_init = 0.0;    // tracked / (frames - initialized_frame); 0 if never
  std::optional<double> ate_rmse_m;         // null without ground truth or alignment
  std::optional<double> ate_rmse_pct_path;  // of the associated ground-truth path length
  double fps = 0.0;                         // frames / wall-clock seconds of the run
  double latency_p50_ms = 0.0;              // arrival -> pose published (or tracked, offline)
  double latency_p99_ms = 0.0;
  double peak_rss_mb = 0.0;

  // Writes the common keys as members of the currently open object.
  void write_json(JsonWriter& w) const;
  // A complete JSON document holding only the common keys.
  std::string to_json() const;
};

// Fills frames, tracked_frames, tracked_ratio, initialized_frame and
// tracked_ratio_after_init from the per-frame tracking states in frame order.
void compute_tracking_stats(const std::vector<TrackingState>& states, RunReport& report);

// Fills latency_p50_ms / latency_p99_ms from per-frame latencies.
void compute_latency_stats(const std::vector<double>& latencies_ms, RunReport& report);

// Tracker time per frame over the frames whose result was in one state (the replay report's
// `init_tracker_ms`: the frames processed while INITIALIZING, before the map exists).
struct StateTiming {
  int64_t frames = 0;            // frames in the state
  std::optional<double> p50_ms;  // empty when no frame was in the state
  std::optional<double> p99_ms;
};
// `states` and `track_ms` are per frame, in frame order, of equal length.
StateTiming tracker_ms_in_state(const std::vector<TrackingState>& states,
                                const std::vector<double>& track_ms, TrackingState state);
// The replay report's `lost_tracker_ms`: the frames processed while LOST (relocalization), i.e.
// the frames after a frame whose result was LOST, whatever their own result.
StateTiming tracker_ms_while_lost(const std::vector<TrackingState>& states,
                                  const std::vector<double>& track_ms);
// Frame count and p50/p99 of `ms` (empty percentiles for no frame).
StateTiming timing_of(const std::vector<double>& ms);

// Fills ate_rmse_m / ate_rmse_pct_path: `estimate` holds the poses of the tracked frames,
// aligned to `ground_truth` with Sim3 (monocular: no metric scale) after association by
// stamp (10 ms). Leaves them empty and returns the reason when evaluation is impossible
// (no ground truth, fewer than 3 associated poses, degenerate motion).
std::string compute_ate(const Trajectory& ground_truth, const Trajectory& estimate,
                        RunReport& report);

}  // namespace rdslam
