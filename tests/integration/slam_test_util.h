// Helpers for the SLAM accuracy tests: a minimal image-list FrameSource (so the tests do not
// depend on the dataset readers), trajectory extraction from offline runs and a one-line
// summary. Test code only.
#pragma once

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "core/frame_source.h"
#include "core/slam.h"
#include "core/trajectory.h"
#include "core/trajectory_eval.h"
#include "drivers/preloaded_frames.h"
#include "firmware_app/config.h"

namespace rdslam::test {

class ImageListSource : public FrameSource {
 public:
  ImageListSource(std::vector<std::string> files, int64_t period_ns)
      : files_(std::move(files)), period_ns_(period_ns) {
    info_.kind = "images";
    info_.frame_count = static_cast<int64_t>(files_.size());
  }
  SourceStatus read(Frame& out, int) override {
    if (next_ >= files_.size()) return SourceStatus::kEndOfStream;
    out.image = cv::imread(files_[next_], cv::IMREAD_GRAYSCALE);
    out.format = PixelFormat::kGray8;
    out.stamp_ns = static_cast<int64_t>(next_) * period_ns_;
    out.seq = next_;
    out.dataset_index = static_cast<int64_t>(next_);
    ++next_;
    return out.image.empty() ? SourceStatus::kFault : SourceStatus::kOk;
  }
  const SourceInfo& info() const override { return info_; }

 private:
  std::vector<std::string> files_;
  int64_t period_ns_;
  size_t next_ = 0;
  SourceInfo info_;
};

inline std::vector<std::string> list_pngs(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() == ".png") out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

inline bool is_tracked(TrackingState s) {
  return s == TrackingState::kTracking || s == TrackingState::kRelocalized;
}

inline Trajectory tracked_trajectory(const OfflineRun& run) {
  Trajectory t;
  for (const auto& f : run.frames) {
    if (!is_tracked(f.result.state)) continue;
    StampedPose p;
    p.stamp_ns = f.stamp_ns;
    p.p_world_cam = f.result.p_world_cam;
    p.q_world_cam = f.result.q_world_cam;
    t.push_back(p);
  }
  return t;
}

struct RunSummary {
  int frames = 0, tracked = 0, first_tracked = -1;
  double tracked_frac = 0, ate_rmse_m = 0, path_m = 0, ate_pct = 0;
  double track_ms_median = 0, track_ms_p99 = 0, mapper_ms_total = 0, track_cpu_ms_median = 0;
  bool eval_ok = false;
};

inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

inline RunSummary summarize(const OfflineRun& run, const Trajectory& gt, const char* name) {
  RunSummary s;
  s.frames = static_cast<int>(run.frames.size());
  std::vector<double> ms, cpu;
  for (size_t i = 0; i < run.frames.size(); ++i) {
    const auto& f = run.frames[i];
    if (is_tracked(f.result.state)) {
      ++s.tracked;
      if (s.first_tracked < 0) s.first_tracked = static_cast<int>(i);
    }
    if (f.result.state != TrackingState::kInitializing) {
      ms.push_back(f.track_ms);
      cpu.push_back(f.track_cpu_ms);
    }
    s.mapper_ms_total += f.mapper_ms;
  }
  s.tracked_frac = s.frames ? double(s.tracked) / s.frames : 0.0;
  s.track_ms_median = percentile(ms, 0.5);
  s.track_ms_p99 = percentile(ms, 0.99);
  s.track_cpu_ms_median = percentile(cpu, 0.5);
  const Trajectory est = tracked_trajectory(run);
  if (!gt.empty() && est.size() >= 3) {
    EvalParams ep;
    ep.align = Alignment::kSim3;
    const EvalResult r = evaluate_trajectories(gt, est, ep);
    if (r.ok) {
      s.eval_ok = true;
      s.ate_rmse_m = r.ate_m.rmse;
      s.path_m = r.gt_path_length_m;
      s.ate_pct = s.path_m > 0 ? 100.0 * s.ate_rmse_m / s.path_m : 0;
    }
  }
  std::printf(
      "[slam] %s: frames %d tracked %d (%.1f%%) first %d | ATE rmse %.4f m over %.2f m "
      "(%.3f%%) | track ms median %.2f (cpu %.2f) p99 %.2f | mapper total %.0f ms | KF %d pts %d "
      "(accepted %d rejected %d culled %d)\n",
      name, s.frames, s.tracked, 100 * s.tracked_frac, s.first_tracked, s.ate_rmse_m, s.path_m,
      s.ate_pct, s.track_ms_median, s.track_cpu_ms_median, s.track_ms_p99, s.mapper_ms_total,
      run.final_keyframes, run.final_points, run.mapper.keyframes_accepted,
      run.mapper.keyframes_rejected, run.mapper.keyframes_culled);
  return s;
}

// Parameters: defaults, the feature mode from RDSLAM_TEST_MODE (sift | orb) and optional
// comma-separated overrides in RDSLAM_TEST_SET ("tracker.m1=100,mapper.m2=60") for
// experiments; the committed tests run with the defaults.
inline SlamParams params_from_env() {
  std::vector<std::string> overrides;
  const char* m = std::getenv("RDSLAM_TEST_MODE");
  if (m && *m) overrides.push_back(std::string("features.mode=") + m);
  if (const char* set = std::getenv("RDSLAM_TEST_SET")) {
    std::string all(set);
    size_t start = 0;
    while (start < all.size()) {
      const size_t comma = all.find(',', start);
      const std::string item =
          all.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      if (!item.empty()) overrides.push_back(item);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  AppConfig cfg = load_config("", overrides);
  cfg.slam.parsac = cfg.parsac;
  return cfg.slam;
}

}  // namespace rdslam::test
