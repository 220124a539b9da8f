#include "firmware_app/report.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "core/trajectory_eval.h"

namespace rdslam {

namespace {

std::string escape(const std::string& s) {
  std::string out;
  out.reserve(s.size() + 2);
  out += '"';
  for (const char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  out += '"';
  return out;
}

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  // 12 significant digits: exact enough for 1e-6 m comparisons of metre-scale values and
  // still readable.
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  return buf;
}

}  // namespace

JsonWriter::JsonWriter() = default;

void JsonWriter::open_item(const char* key) {
  if (first_.empty()) {
    if (!out_.empty()) throw std::logic_error("JsonWriter: more than one root value");
    return;
  }
  if (!first_.back()) out_ += ',';
  first_.back() = false;
  out_ += '\n';
  out_.append(2 * first_.size(), ' ');
  if (key) out_ += escape(key) + ": ";
}

JsonWriter& JsonWriter::begin_object(const char* key) {
  open_item(key);
  out_ += '{';
  first_.push_back(true);
  return *this;
}

JsonWriter& JsonWriter::end_object() {
  return close('}');
}

JsonWriter& JsonWriter::close(char bracket) {
  if (first_.empty()) throw std::logic_error("JsonWriter: closing more than was opened");
  const bool empty = first_.back();
  first_.pop_back();
  if (!empty) {
    out_ += '\n';
    out_.append(2 * first_.size(), ' ');
  }
  out_ += bracket;
  return *this;
}

JsonWriter& JsonWriter::begin_array(const char* key) {
  open_item(key);
  out_ += '[';
  first_.push_back(true);
  return *this;
}

JsonWriter& JsonWriter::end_array() {
  return close(']');
}

JsonWriter& JsonWriter::value(const char* key, double v) {
  open_item(key);
  out_ += number(v);
  return *this;
}

JsonWriter& JsonWriter::value(const char* key, int64_t v) {
  open_item(key);
  out_ += std::to_string(v);
  return *this;
}

JsonWriter& JsonWriter::value(const char* key, bool v) {
  open_item(key);
  out_ += v ? "true" : "false";
  return *this;
}

JsonWriter& JsonWriter::value(const char* key, const std::string& v) {
  open_item(key);
  out_ += escape(v);
  return *this;
}

JsonWriter& JsonWriter::value(const char* key, const std::optional<double>& v) {
  return v ? value(key, *v) : null(key);
}

JsonWriter& JsonWriter::null(const char* key) {
  open_item(key);
  out_ += "null";
  return *this;
}

JsonWriter& JsonWriter::element(double v) {
  open_item(nullptr);
  out_ += number(v);
  return *this;
}

std::string JsonWriter::str() const {
  if (!first_.empty()) throw std::logic_error("JsonWriter: unclosed object or array");
  return out_ + "\n";
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  q = std::clamp(q, 0.0, 1.0);
  const double pos = q * static_cast<double>(values.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, values.size() - 1);
  return values[lo] + (pos - static_cast<double>(lo)) * (values[hi] - values[lo]);
}

double peak_rss_mb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    long kib = 0;
    if (std::sscanf(line.c_str(), "VmHWM: %ld kB", &kib) == 1) return kib / 1024.0;
  }
  struct rusage ru {};
  if (getrusage(RUSAGE_SELF, &ru) == 0) return ru.ru_maxrss / 1024.0;  // KiB on Linux
  return 0.0;
}

void RunReport::write_json(JsonWriter& w) const {
  w.value("frames", frames)
      .value("tracked_frames", tracked_frames)
      .value("tracked_ratio", tracked_ratio)
      .value("initialized_frame", initialized_frame)
      .value("tracked_ratio_after_init", tracked_ratio_after_init)
      .value("ate_rmse_m", ate_rmse_m)
      .value("ate_rmse_pct_path", ate_rmse_pct_path)
      .value("fps", fps)
      .begin_object("latency_ms")
      .value("p50", latency_p50_ms)
      .value("p99", latency_p99_ms)
      .end_object()
      .value("peak_rss_mb", peak_rss_mb);
}

std::string RunReport::to_json() const {
  JsonWriter w;
  w.begin_object();
  write_json(w);
  w.end_object();
  return w.str();
}

void compute_tracking_stats(const std::vector<TrackingState>& states, RunReport& report) {
  report.frames = static_cast<int64_t>(states.size());
  report.tracked_frames = 0;
  report.initialized_frame = -1;
  int64_t tracked_after_init = 0;
  for (size_t i = 0; i < states.size(); ++i) {
    const TrackingState s = states[i];
    if (report.initialized_frame < 0 && s == TrackingState::kTracking) {
      report.initialized_frame = static_cast<int64_t>(i);
    }
    // RELOCALIZED is the first supported pose after a loss: it counts as tracked.
    const bool tracked = s == TrackingState::kTracking || s == TrackingState::kRelocalized;
    if (tracked) {
      ++report.tracked_frames;
      if (report.initialized_frame >= 0) ++tracked_after_init;
    }
  }
  report.tracked_ratio =
      report.frames > 0 ? static_cast<double>(report.tracked_frames) / report.frames : 0.0;
  report.tracked_ratio_after_init =
      report.initialized_frame >= 0
          ? static_cast<double>(tracked_after_init) / (report.frames - report.initialized_frame)
          : 0.0;
}

void compute_latency_stats(const std::vector<double>& latencies_ms, RunReport& report) {
  report.latency_p50_ms = percentile(latencies_ms, 0.50);
  report.latency_p99_ms = percentile(latencies_ms, 0.99);
}

StateTiming tracker_ms_in_state(const std::vector<TrackingState>& states,
                                const std::vector<double>& track_ms, TrackingState state) {
  std::vector<double> v;
  for (size_t i = 0; i < states.size() && i < track_ms.size(); ++i) {
    if (states[i] == state) v.push_back(track_ms[i]);
  }
  return timing_of(v);
}

StateTiming tracker_ms_while_lost(const std::vector<TrackingState>& states,
                                  const std::vector<double>& track_ms) {
  // A frame is processed in the LOST state when the frame before it ended LOST: relocalization
  // ran on it, whatever its own result (LOST, RELOCALIZED, or INITIALIZING after a reset).
  std::vector<double> v;
  for (size_t i = 1; i < states.size() && i < track_ms.size(); ++i) {
    if (states[i - 1] == TrackingState::kLost) v.push_back(track_ms[i]);
  }
  return timing_of(v);
}

StateTiming timing_of(const std::vector<double>& v) {
  StateTiming t;
  t.frames = static_cast<int64_t>(v.size());
  if (!v.empty()) {
    t.p50_ms = percentile(v, 0.5);
    t.p99_ms = percentile(v, 0.99);
  }
  return t;
}

std::string compute_ate(const Trajectory& ground_truth, const Trajectory& estimate,
                        RunReport& report) {
  report.ate_rmse_m.reset();
  report.ate_rmse_pct_path.reset();
  if (ground_truth.empty()) return "no ground truth";
  if (estimate.empty()) return "no tracked pose";
  EvalParams params;
  params.align = Alignment::kSim3;
  const EvalResult r = evaluate_trajectories(ground_truth, estimate, params);
  if (!r.ok) return r.error;
  report.ate_rmse_m = r.ate_m.rmse;
  if (r.gt_path_length_m > 0.0) report.ate_rmse_pct_path = r.ate_pct_path.rmse;
  return {};
}

}  // namespace rdslam
