// `rdslam eval GROUNDTRUTH ESTIMATE`: ATE and RPE of an estimated trajectory against ground
// truth (core/trajectory_eval.h), as text or JSON, with an optional PNG plot.
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>

#include "core/trajectory.h"
#include "core/trajectory_eval.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"
#include "firmware_app/plot.h"
#include "firmware_app/report.h"

namespace rdslam {

namespace {

const char* format_name(TrajectoryFormat f) {
  switch (f) {
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kEuroc:
      return "euroc";
    case TrajectoryFormat::kKitti:
      return "kitti";
  }
  return "?";
}

TrajectoryFormat resolve_format(const std::string& option, const char* flag,
                                const std::string& path) {
  if (option.empty() || option == "auto") return detect_trajectory_format(path);
  if (option == "tum") return TrajectoryFormat::kTum;
  if (option == "euroc") return TrajectoryFormat::kEuroc;
  if (option == "kitti") return TrajectoryFormat::kKitti;
  throw UsageError(std::string("option '") + flag + "': '" + option +
                   "' is not a trajectory format; allowed tum, euroc, kitti, auto");
}

void print_stats_line(const char* name, const ErrorStats& s, const char* unit, int decimals) {
  std::printf("%-15s rmse %.*f  mean %.*f  median %.*f  max %.*f %s\n", name, decimals, s.rmse,
              decimals, s.mean, decimals, s.median, decimals, s.max, unit);
}

void json_stats(JsonWriter& w, const char* key, const ErrorStats& s) {
  w.begin_object(key)
      .value("count", s.count)
      .value("rmse", s.rmse)
      .value("mean", s.mean)
      .value("median", s.median)
      .value("max", s.max)
      .value("min", s.min)
      .value("std", s.std)
      .end_object();
}

}  // namespace

int cmd_eval(int argc, char** argv) {
  std::string gt_path, est_path, align_text = "sim3", plot_path, fmt_gt, fmt_est;
  bool json = false;
  double max_diff_s = 0.01;
  double rpe_delta = 1;
  double kitti_rate_hz = 10.0;
  ArgParser p(
      "rdslam eval GROUNDTRUTH ESTIMATE [--align sim3|se3|none] [--json] [--plot OUT.png]\n"
      "                   [--format-gt tum|euroc|kitti] [--format-est tum|euroc|kitti]",
      "Absolute trajectory error (ATE) and relative pose error (RPE) of ESTIMATE against\n"
      "GROUNDTRUTH. Formats: TUM (t tx ty tz qx qy qz qw), EuRoC (state_groundtruth csv) and\n"
      "KITTI (3x4 poses), detected from the content unless given. Poses are associated by\n"
      "timestamp (nearest within --max-diff), two KITTI files by index; a KITTI file evaluated\n"
      "against a timed one gets stamps index / --kitti-rate. The estimate is aligned with\n"
      "Umeyama's method (sim3: rotation, translation, scale, the default for monocular SLAM).\n"
      "ATE is reported in metres and in % of the associated ground-truth path length; RPE over\n"
      "pairs of associated poses --rpe-delta apart. Definitions match evo (evo_ape/evo_rpe).");
  p.positional("GROUNDTRUTH", &gt_path, "ground-truth trajectory file");
  p.positional("ESTIMATE", &est_path, "estimated trajectory file");
  p.option("--align", &align_text, "MODE", "sim3 (default), se3 or none");
  p.flag("--json", &json, "print the result as JSON on stdout");
  p.option("--plot", &plot_path, "OUT.png", "write a PNG: top view of both trajectories, ATE");
  p.option("--format-gt", &fmt_gt, "FMT", "tum, euroc, kitti or auto (default)");
  p.option("--format-est", &fmt_est, "FMT", "tum, euroc, kitti or auto (default)");
  p.option("--max-diff", &max_diff_s, "SECONDS", "max stamp difference to associate (0.01)");
  p.option("--rpe-delta", &rpe_delta, "N", "RPE pair distance in associated poses (1)");
  p.option("--kitti-rate", &kitti_rate_hz, "HZ", "frame rate giving KITTI poses stamps (10)");
  if (!p.parse(argc, argv)) return 0;

  EvalParams params;
  if (!parse_alignment(align_text, params.align)) {
    throw UsageError("option '--align': '" + align_text +
                     "' is not allowed; allowed sim3, se3, "
                     "none");
  }
  if (!(max_diff_s >= 0.0) || max_diff_s > 1e6) {
    throw UsageError("option '--max-diff': must be a number of seconds >= 0");
  }
  if (rpe_delta < 1 || rpe_delta != std::floor(rpe_delta) || rpe_delta > 1e9) {
    throw UsageError("option '--rpe-delta': must be a whole number >= 1");
  }
  if (!(kitti_rate_hz > 0.0)) throw UsageError("option '--kitti-rate': must be > 0");
  params.max_diff_ns = static_cast<int64_t>(std::llround(max_diff_s * 1e9));
  params.rpe_delta = static_cast<int>(rpe_delta);

  const TrajectoryFormat f_gt = resolve_format(fmt_gt, "--format-gt", gt_path);
  const TrajectoryFormat f_est = resolve_format(fmt_est, "--format-est", est_path);
  const int64_t kitti_period_ns = static_cast<int64_t>(std::llround(1e9 / kitti_rate_hz));
  const Trajectory gt = read_trajectory(gt_path, f_gt, kitti_period_ns);
  const Trajectory est = read_trajectory(est_path, f_est, kitti_period_ns);
  params.by_index = f_gt == TrajectoryFormat::kKitti && f_est == TrajectoryFormat::kKitti;
  if (params.by_index && gt.size() != est.size()) {
    std::fprintf(stderr,
                 "rdslam eval: warning: KITTI files associated by index but they have %zu and "
                 "%zu poses; only the first %zu are compared\n",
                 gt.size(), est.size(), std::min(gt.size(), est.size()));
  }

  const EvalResult r = evaluate_trajectories(gt, est, params);
  if (!r.ok) {
    std::fprintf(stderr, "rdslam eval: cannot evaluate '%s' against '%s': %s\n", est_path.c_str(),
                 gt_path.c_str(), r.error.c_str());
    return 1;
  }

  if (json) {
    JsonWriter w;
    w.begin_object()
        .value("ground_truth", gt_path)
        .value("estimate", est_path)
        .value("format_gt", format_name(f_gt))
        .value("format_est", format_name(f_est))
        .value("association", params.by_index ? "index" : "time")
        .value("max_diff_s", max_diff_s)
        .value("gt_poses", r.gt_poses)
        .value("est_poses", r.est_poses)
        .value("pairs", r.pairs.size())
        .begin_object("alignment")
        .value("mode", to_string(params.align))
        .value("scale", r.alignment.scale)
        .begin_array("rotation");
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) w.element(r.alignment.R(i, j));
    }
    w.end_array().begin_array("translation");
    for (int i = 0; i < 3; ++i) w.element(r.alignment.t(i));
    w.end_array()
        .end_object()
        .value("gt_path_length_m", r.gt_path_length_m)
        .value("ate_rmse_m", r.ate_m.rmse)
        // A ground truth that never moves has no path to relate the error to: null.
        .value("ate_rmse_pct_path", r.gt_path_length_m > 0.0
                                        ? std::optional<double>(r.ate_pct_path.rmse)
                                        : std::nullopt);
    json_stats(w, "ate_m", r.ate_m);
    json_stats(w, "ate_pct_path", r.ate_pct_path);
    w.value("rpe_delta_frames", params.rpe_delta);
    json_stats(w, "rpe_trans_m", r.rpe_trans_m);
    json_stats(w, "rpe_rot_deg", r.rpe_rot_deg);
    w.end_object();
    std::fputs(w.str().c_str(), stdout);
  } else {
    std::printf("ground truth    %s (%s, %zu poses)\n", gt_path.c_str(), format_name(f_gt),
                r.gt_poses);
    std::printf("estimate        %s (%s, %zu poses)\n", est_path.c_str(), format_name(f_est),
                r.est_poses);
    if (params.by_index) {
      std::printf("associated      %zu pairs by index\n", r.pairs.size());
    } else {
      std::printf("associated      %zu pairs by timestamp (max diff %g s)\n", r.pairs.size(),
                  max_diff_s);
    }
    std::printf("alignment       %s, scale %.6f\n", to_string(params.align), r.alignment.scale);
    std::printf("gt path length  %.4f m\n", r.gt_path_length_m);
    print_stats_line("ATE", r.ate_m, "m", 6);
    print_stats_line("ATE % of path", r.ate_pct_path, "%", 4);
    char name[32];
    std::snprintf(name, sizeof(name), "RPE trans d=%d", params.rpe_delta);
    print_stats_line(name, r.rpe_trans_m, "m", 6);
    std::snprintf(name, sizeof(name), "RPE rot d=%d", params.rpe_delta);
    print_stats_line(name, r.rpe_rot_deg, "deg", 4);
    if (r.rpe_trans_m.count == 0) std::printf("(RPE: fewer than delta+1 associated poses)\n");
  }

  if (!plot_path.empty()) {
    TrajectoryPlot plot;
    char title[256];
    std::snprintf(title, sizeof(title),
                  "ATE (%s) RMSE %.4f m = %.3f %% of %.2f m path, max %.4f m, %zu poses",
                  to_string(params.align), r.ate_m.rmse, r.ate_pct_path.rmse, r.gt_path_length_m,
                  r.ate_m.max, r.pairs.size());
    plot.title = std::string(title) + "\nground truth: " + gt_path + "\nestimate: " + est_path;
    // KITTI poses live in a camera frame (y down); EuRoC ground truth in a z-up world; TUM
    // files can be either, so the plot drops the axis of least extent for them.
    plot.up_axis = f_gt == TrajectoryFormat::kKitti ? 1 : f_gt == TrajectoryFormat::kEuroc ? 2 : -1;
    plot.up_is_negative = f_gt == TrajectoryFormat::kKitti;
    plot.tracks.push_back({"ground truth", cv::Scalar(40, 40, 40), r.gt_positions, 2});
    plot.tracks.push_back({std::string("estimate (") + to_string(params.align) + " aligned)",
                           cv::Scalar(200, 110, 20), r.est_positions_aligned, 2});
    PlotCurve ate{"ATE per pose", cv::Scalar(30, 30, 210), {}, r.ate_errors_m};
    for (int64_t s : r.stamps_ns) ate.t_s.push_back((s - r.stamps_ns.front()) * 1e-9);
    plot.curves.push_back(ate);
    plot.curve_title = "absolute trajectory error over time";
    write_trajectory_plot(plot, plot_path);
    if (!json) std::printf("plot            %s\n", plot_path.c_str());
  }
  return 0;
}

}  // namespace rdslam
