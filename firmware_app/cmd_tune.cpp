// `rdslam tune`: threshold search per environment (issue 27; docs/tune.md). The search itself
// (parameter file, sampling, successive halving, objectives, results file) is
// firmware_app/tune.h; this file runs each evaluation as a child `rdslam replay` process
// (isolates crashes; --jobs J children at a time), shows progress, prints the results table,
// draws the PNG and writes best.yaml.
#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "core/trajectory.h"
#include "core/trajectory_eval.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"
#include "firmware_app/tune.h"

extern char** environ;

namespace rdslam {

namespace {

namespace fs = std::filesystem;

// `--sequences A B C` -> `--sequences A --sequences B --sequences C` (the parser takes one
// value per option).
std::vector<std::string> expand_lists(int argc, char** argv) {
  std::vector<std::string> out;
  std::string list_opt;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sequences" || a == "--holdout") {
      list_opt = a;
      continue;
    }
    if (!list_opt.empty() && (a.size() < 2 || a.compare(0, 2, "--") != 0)) {
      out.push_back(list_opt);
      out.push_back(a);
      continue;
    }
    list_opt.clear();
    out.push_back(a);
  }
  return out;
}

std::string with_frames(const std::string& uri, int frames) {
  if (frames <= 0) return uri;
  if (uri.rfind("synth:", 0) != 0) {
    throw UsageError("--frames: shortens synth: sequences only, not '" + uri + "'");
  }
  if (uri.find("frames=") != std::string::npos) {
    throw UsageError("--frames: '" + uri + "' already sets frames=");
  }
  return uri + (uri.find('?') == std::string::npos ? "?" : "&") +
         "frames=" + std::to_string(frames);
}

std::string self_exe() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot find the rdslam executable (/proc/self/exe)");
  return p.string();
}

// The results of one finished replay (its report and trajectories in `dir`).
SeqResult read_run(const fs::path& dir, int exit_status, double wall_s) {
  SeqResult r;
  r.wall_s = wall_s;
  const fs::path report = dir / "report.json";
  if (exit_status != 0 || !fs::exists(report)) {
    r.error = "replay exited with status " + std::to_string(exit_status) + " (see " +
              (dir / "log.txt").string() + ")";
    return r;
  }
  YAML::Node n;
  try {
    n = YAML::LoadFile(report.string());
  } catch (const YAML::Exception& e) {
    r.error = "cannot parse " + report.string() + ": " + e.msg;
    return r;
  }
  auto num = [](const YAML::Node& v) -> std::optional<double> {
    if (!v || !v.IsScalar() || v.Scalar() == "null") return std::nullopt;
    try {
      return v.as<double>();
    } catch (const YAML::Exception&) {
      return std::nullopt;
    }
  };
  r.ok = true;
  r.initialized = num(n["initialized_frame"]).value_or(-1.0) >= 0.0;
  r.tracked_ratio = num(n["tracked_ratio"]).value_or(0.0);
  r.tracked_ratio_after_init = num(n["tracked_ratio_after_init"]).value_or(0.0);
  r.ate_pct = num(n["ate_rmse_pct_path"]);
  if (n["ate_final"]) r.ate_final_pct = num(n["ate_final"]["rmse_pct_path"]);
  // Consistency: the online poses against the final (bundle-adjusted) ones of the same run.
  try {
    const Trajectory online =
        read_trajectory((dir / "online.tum").string(), TrajectoryFormat::kTum);
    const Trajectory final_t =
        read_trajectory((dir / "final.tum").string(), TrajectoryFormat::kTum);
    std::vector<Eigen::Vector3d> positions;
    for (const auto& sp : online) positions.push_back(sp.p_world_cam);
    r.roughness_pct = trajectory_roughness_pct(positions);
    if (online.size() >= 3 && final_t.size() >= 3) {
      const EvalResult er = evaluate_trajectories(final_t, online, EvalParams{});
      if (er.ok && er.gt_path_length_m > 0.0) r.consistency_pct = er.ate_pct_path.rmse;
    }
  } catch (const std::exception&) {
    // no trajectory (never tracked): consistency stays empty, the score is a failure
  }
  return r;
}

struct Runner {
  std::string exe;
  fs::path runs_dir;
  std::string config_path;             // base --config ("" none)
  std::vector<std::string> base_sets;  // base --set
  int jobs = 1;

  void operator()(const std::vector<EvalRequest>& reqs,
                  const std::function<void(size_t, const SeqResult&)>& done) const {
    struct Running {
      size_t index;
      std::chrono::steady_clock::time_point start;
    };
    std::map<pid_t, Running> running;
    size_t next = 0;
    while (next < reqs.size() || !running.empty()) {
      while (next < reqs.size() && static_cast<int>(running.size()) < jobs) {
        const EvalRequest& q = reqs[next];
        const fs::path dir = runs_dir / q.key;
        fs::create_directories(dir);
        for (const char* f : {"report.json", "online.tum", "final.tum"}) fs::remove(dir / f);
        std::vector<std::string> args = {exe, "replay", with_frames(q.sequence, q.frames)};
        if (q.use_base_config) {
          if (!config_path.empty()) args.insert(args.end(), {"--config", config_path});
          for (const auto& s : base_sets) args.insert(args.end(), {"--set", s});
        }
        for (const auto& s : q.overrides) args.insert(args.end(), {"--set", s});
        args.insert(args.end(), {"--report", (dir / "report.json").string(), "--trajectory",
                                 (dir / "online.tum").string(), "--final-trajectory",
                                 (dir / "final.tum").string()});
        std::vector<char*> argv;
        for (auto& a : args) argv.push_back(a.data());
        argv.push_back(nullptr);
        posix_spawn_file_actions_t fa;
        posix_spawn_file_actions_init(&fa);
        const std::string log = (dir / "log.txt").string();
        posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        posix_spawn_file_actions_adddup2(&fa, 1, 2);
        pid_t pid = 0;
        const int rc = posix_spawn(&pid, exe.c_str(), &fa, nullptr, argv.data(), environ);
        posix_spawn_file_actions_destroy(&fa);
        if (rc != 0) {
          SeqResult failed;
          failed.error = "cannot start " + exe;
          done(next, failed);
        } else {
          running[pid] = {next, std::chrono::steady_clock::now()};
        }
        ++next;
      }
      if (running.empty()) continue;
      int status = 0;
      const pid_t pid = waitpid(-1, &status, 0);
      if (pid < 0) throw std::runtime_error("waitpid failed");
      const auto it = running.find(pid);
      if (it == running.end()) continue;
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.start)
              .count();
      const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      const size_t i = it->second.index;
      running.erase(it);
      done(i, read_run(runs_dir / reqs[i].key, code, wall));
    }
  }
};

// One status line on stderr: redrawn in place on a terminal, a plain line every 10% otherwise.
class TuneBar {
 public:
  TuneBar() : terminal_(isatty(fileno(stderr)) == 1) {}
  void operator()(size_t finished, size_t total, const std::string& what) {
    if (total == 0) {
      std::fprintf(stderr, "tune: %s: all runs found in results.jsonl\n", what.c_str());
      return;
    }
    const size_t pct = finished * 100 / total;
    if (!terminal_) {
      if (finished != 0 && finished != total && pct / 10 == last_pct_ / 10) return;
      last_pct_ = pct;
      std::fprintf(stderr, "tune: %s: %zu/%zu runs (%zu%%)\n", what.c_str(), finished, total, pct);
      return;
    }
    std::string bar(30, '.');
    std::fill(bar.begin(), bar.begin() + static_cast<long>(pct * 30 / 100), '#');
    std::fprintf(stderr, "\r[%s] %3zu%% %zu/%zu runs  %s", bar.c_str(), pct, finished, total,
                 what.c_str());
    if (finished == total) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  bool terminal_;
  size_t last_pct_ = 0;
};

std::string fmt_opt(const std::optional<double>& v, const char* f = "%.3f") {
  if (!v) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), f, *v);
  return buf;
}

// Scatter panels: rung-0 objective against each of the most influential parameters.
void write_plot(const TuneSetup& setup, const TuneOutcome& out, const std::vector<size_t>& order,
                const std::vector<double>& influence, const std::string& path) {
  const int panels = static_cast<int>(std::min<size_t>(3, order.size()));
  const int w = 420, h = 360, ml = 60, mr = 15, mt = 40, mb = 50;
  cv::Mat img(h, w * panels, CV_8UC3, cv::Scalar(255, 255, 255));
  double ymin = 1e300, ymax = -1e300;
  for (const auto& c : out.candidates) {
    if (c.rung0_objective >= kFailureScore) continue;
    ymin = std::min(ymin, c.rung0_objective);
    ymax = std::max(ymax, c.rung0_objective);
  }
  if (ymin > ymax) ymin = 0, ymax = 1;
  if (ymax - ymin < 1e-9) ymax = ymin + 1.0;
  const double pad = 0.05 * (ymax - ymin);
  ymin -= pad, ymax += pad;
  for (int k = 0; k < panels; ++k) {
    const size_t pi = order[static_cast<size_t>(k)];
    const TuneParam& p = setup.params[pi];
    const int x0 = k * w + ml, x1 = (k + 1) * w - mr, y0 = mt, y1 = h - mb;
    auto tx = [&](double v) {
      const double a = p.log_scale ? std::log(p.min) : p.min;
      const double b = p.log_scale ? std::log(p.max) : p.max;
      const double t = ((p.log_scale ? std::log(v) : v) - a) / (b - a);
      return x0 + static_cast<int>(std::lround(t * (x1 - x0)));
    };
    auto ty = [&](double v) {
      if (v >= kFailureScore) return y0 + 4;  // failures on the top edge
      return y1 - static_cast<int>(std::lround((v - ymin) / (ymax - ymin) * (y1 - y0)));
    };
    cv::rectangle(img, {x0, y0}, {x1, y1}, cv::Scalar(0, 0, 0), 1);
    char title[160];
    std::snprintf(title, sizeof(title), "%s  |rho|=%.2f", p.name.c_str(), influence[pi]);
    cv::putText(img, title, {k * w + 10, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1,
                cv::LINE_AA);
    for (double t : {0.0, 0.5, 1.0}) {
      const double v = p.log_scale ? std::exp(std::log(p.min) + t * std::log(p.max / p.min))
                                   : p.min + t * (p.max - p.min);
      const std::string s = format_tune_value(p, v);
      cv::putText(img, s, {tx(v) - 12, y1 + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.4, {0, 0, 0}, 1,
                  cv::LINE_AA);
    }
    for (double t : {0.0, 0.5, 1.0}) {
      char s[32];
      std::snprintf(s, sizeof(s), "%.3g", ymin + pad + t * (ymax - ymin - 2 * pad));
      cv::putText(img, s, {k * w + 5, ty(ymin + pad + t * (ymax - ymin - 2 * pad)) + 4},
                  cv::FONT_HERSHEY_SIMPLEX, 0.4, {0, 0, 0}, 1, cv::LINE_AA);
    }
    cv::putText(img,
                std::string(to_string(setup.objective)) +
                    " objective (rung 1); green best, blue start, red x failed",
                {k * w + 10, h - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.4, {80, 80, 80}, 1, cv::LINE_AA);
    for (size_t ci = 0; ci < out.candidates.size(); ++ci) {
      const auto& c = out.candidates[ci];
      const cv::Point pt(tx(c.candidate.values[pi]), ty(c.rung0_objective));
      cv::Scalar col(150, 150, 150);
      if (static_cast<int>(ci) == out.best) col = cv::Scalar(0, 170, 0);
      if (ci == 0) col = cv::Scalar(220, 80, 0);
      if (c.rung0_objective >= kFailureScore) {
        cv::drawMarker(img, pt, cv::Scalar(0, 0, 220), cv::MARKER_TILTED_CROSS, 9, 1);
      } else {
        cv::circle(img, pt, ci == 0 || static_cast<int>(ci) == out.best ? 6 : 4, col, cv::FILLED,
                   cv::LINE_AA);
      }
    }
  }
  if (!cv::imwrite(path, img)) throw std::runtime_error("cannot write " + path);
}

// best.yaml: every key of the effective configuration that differs from the built-in
// defaults, grouped by section, with a header saying where it came from.
void write_best_yaml(const std::string& path, const std::string& header, AppConfig& cfg) {
  std::map<std::string, std::vector<std::pair<std::string, std::string>>> sections;
  std::vector<std::pair<std::string, std::string>> top;
  for (const auto& kv : non_default_params(cfg)) {
    const size_t eq = kv.find('=');
    const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
    const size_t dot = key.find('.');
    if (dot == std::string::npos) {
      top.emplace_back(key, value);
    } else {
      sections[key.substr(0, dot)].emplace_back(key.substr(dot + 1), value);
    }
  }
  auto quoted = [](const std::string& v) {
    const bool q = v.empty() || v.find_first_of(":#'\"") != std::string::npos;
    return q ? "\"" + v + "\"" : v;
  };
  std::ostringstream os;
  os << header;
  for (const auto& [k, v] : top) os << k << ": " << quoted(v) << "\n";
  for (const auto& [s, kvs] : sections) {
    os << s << ":\n";
    for (const auto& [k, v] : kvs) os << "  " << k << ": " << quoted(v) << "\n";
  }
  std::ofstream f(path);
  f << os.str();
  if (!f.flush()) throw std::runtime_error("cannot write " + path);
}

}  // namespace

int cmd_tune(int argc, char** argv) {
  std::vector<std::string> sequences, holdout, base_sets;
  std::string params_path, config_path, objective_text = "ate", out_dir = "tune_out", best_path,
                                        plot_path;
  double budget = 24, jobs = 1, seed = 1, frames = 0, rungs = 1;
  ArgParser p(
      "rdslam tune --sequences S1 [S2 ...] --params FILE --budget N [--objective ate|consistency] "
      "[--holdout H1 [H2 ...]] [--jobs J] [--seed S] [--frames N [--rungs R]] [--out best.yaml] "
      "[--out-dir DIR] [--config F] [--set K=V]",
      "Search the configuration keys listed in FILE (docs/tune/example.yaml) over recorded or\n"
      "synthetic sequences: random search with successive halving, each evaluation a child\n"
      "`rdslam replay` (the real pipeline). Every finished run is appended to\n"
      "DIR/results.jsonl; running the same command again skips what is done. Prints a results\n"
      "table, writes DIR/tune.png (objective against the most influential parameters) and the\n"
      "best configuration as YAML for `rdslam run/replay --config` (docs/tune.md).");
  p.repeated("--sequences", &sequences, "S1 [S2 ...]",
             "search sequences (any source URI: synth:NAME, tum:DIR, ...)");
  p.option("--params", &params_path, "FILE",
           "the searched keys: list of {name, min, max, scale, type}");
  p.option("--budget", &budget, "N",
           "configuration evaluations (one configuration on all search sequences at one rung), "
           "including the start configuration (default 24)");
  p.option("--objective", &objective_text, "ate|consistency",
           "ate: ATE % of path (needs ground truth); consistency: online vs final trajectory "
           "agreement plus path roughness plus disagreement with the other configurations that "
           "track the sequence, no ground truth (default ate; docs/tune.md)");
  p.repeated("--holdout", &holdout, "H1 [H2 ...]",
             "sequences never used in the search: the defaults, the start and the best "
             "configuration are compared on them");
  p.option("--jobs", &jobs, "J", "replays run at a time (default 1)");
  p.option("--seed", &seed, "S", "seed of the candidate sampler (default 1)");
  p.option("--frames", &frames, "N",
           "use the first N frames of each synth: sequence (default: all frames)");
  p.option("--rungs", &rungs, "R",
           "successive-halving rungs (eta 3) over frame counts N/3^(R-1), ..., N; needs --frames "
           "(default 1: plain random search)");
  p.option("--out", &best_path, "FILE", "the best configuration (default DIR/best.yaml)");
  p.option("--out-dir", &out_dir, "DIR",
           "results.jsonl, runs/ (each replay's report, trajectories, log), tune.png (default "
           "tune_out)");
  p.option("--plot", &plot_path, "FILE", "the PNG (default DIR/tune.png)");
  p.config_options(&config_path, &base_sets);
  std::vector<std::string> args = expand_lists(argc, argv);
  std::vector<char*> av;
  for (auto& a : args) av.push_back(a.data());
  if (!p.parse(static_cast<int>(av.size()), av.data())) return 0;

  if (sequences.empty()) throw UsageError("--sequences: at least one sequence is needed");
  if (params_path.empty()) throw UsageError("--params: the parameter file is needed");
  auto int_opt = [](const char* name, double v, double lo, double hi) {
    if (v != std::floor(v) || v < lo || v > hi) {
      char buf[160];
      std::snprintf(buf, sizeof(buf), "%s: must be an integer in [%g, %g]", name, lo, hi);
      throw UsageError(buf);
    }
    return static_cast<int>(v);
  };
  const int n_budget = int_opt("--budget", budget, 2, 100000);
  const int n_jobs = int_opt("--jobs", jobs, 1, 256);
  const int n_frames = int_opt("--frames", frames, 0, 10000000);
  const int n_rungs = int_opt("--rungs", rungs, 1, 10);
  if (seed < 0 || seed != std::floor(seed) || seed > 9e15) {
    throw UsageError("--seed: must be a non-negative integer");
  }
  TuneSetup setup;
  if (!parse_tune_objective(objective_text, setup.objective)) {
    throw UsageError("--objective: '" + objective_text + "' is not ate or consistency");
  }
  for (const auto& s : sequences) with_frames(s, n_frames);  // checked before any run
  for (const auto& s : holdout) with_frames(s, n_frames);
  for (const auto& s : holdout) {
    if (std::find(sequences.begin(), sequences.end(), s) != sequences.end()) {
      throw UsageError("--holdout: '" + s + "' is also a search sequence");
    }
  }
  try {
    setup.plan = plan_halving(n_budget, n_rungs, n_frames);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  setup.params = load_tune_params(params_path);
  AppConfig base = load_cli_config(config_path, base_sets);
  setup.start = tune_start_values(base, setup.params);
  setup.sequences = sequences;
  setup.holdout = holdout;
  setup.seed = static_cast<uint64_t>(seed);
  setup.base_identity = dump_config(base);

  fs::create_directories(out_dir);
  if (best_path.empty()) best_path = (fs::path(out_dir) / "best.yaml").string();
  if (plot_path.empty()) plot_path = (fs::path(out_dir) / "tune.png").string();
  ResultStore store((fs::path(out_dir) / "results.jsonl").string());
  Runner runner;
  runner.exe = self_exe();
  runner.runs_dir = fs::path(out_dir) / "runs";
  setup.online_trajectory = [dir = runner.runs_dir](const std::string& key) {
    try {
      return read_trajectory((dir / key / "online.tum").string(), TrajectoryFormat::kTum);
    } catch (const std::exception&) {
      return Trajectory{};  // never tracked, or the run's files are gone: no trajectory
    }
  };
  runner.config_path = config_path.empty() ? "" : fs::absolute(config_path).string();
  runner.base_sets = base_sets;
  runner.jobs = n_jobs;
  std::fprintf(stderr,
               "tune: %zu parameters, %zu search sequences, %zu holdout, objective %s, plan",
               setup.params.size(), sequences.size(), holdout.size(), to_string(setup.objective));
  for (size_t r = 0; r < setup.plan.configs.size(); ++r) {
    std::fprintf(stderr, " %d configs x %s", setup.plan.configs[r],
                 setup.plan.frames[r] > 0
                     ? (std::to_string(setup.plan.frames[r]) + " frames").c_str()
                     : "all frames");
  }
  std::fprintf(stderr, "; %zu earlier runs in %s/results.jsonl\n", store.loaded(), out_dir.c_str());
  TuneBar bar;
  const auto t0 = std::chrono::steady_clock::now();
  const TuneOutcome out = run_tune(
      setup, runner, store, [&bar](size_t f, size_t t, const std::string& w) { bar(f, t, w); });
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // Influence: |Spearman| between each parameter and the rung-0 objective.
  std::vector<double> objective0;
  for (const auto& c : out.candidates) objective0.push_back(c.rung0_objective);
  std::vector<double> influence;
  for (size_t i = 0; i < setup.params.size(); ++i) {
    std::vector<double> xs;
    for (const auto& c : out.candidates) xs.push_back(c.candidate.values[i]);
    influence.push_back(std::fabs(spearman(xs, objective0)));
  }
  std::vector<size_t> order(setup.params.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return influence[a] > influence[b]; });

  // Results table: candidates by (rung reached desc, objective asc).
  std::vector<size_t> rank(out.candidates.size());
  for (size_t i = 0; i < rank.size(); ++i) rank[i] = i;
  std::stable_sort(rank.begin(), rank.end(), [&](size_t a, size_t b) {
    const auto &ca = out.candidates[a], &cb = out.candidates[b];
    if (ca.rung != cb.rung) return ca.rung > cb.rung;
    return ca.objective < cb.objective;
  });
  std::printf("\nrdslam tune: %d configurations, %d replays (%d from results.jsonl), %.0f s\n",
              static_cast<int>(out.candidates.size()), out.runs_total, out.runs_resumed, wall);
  const bool show_x = setup.objective == TuneObjective::kConsistency;
  std::printf("%-4s %-5s %-5s %-10s %-10s", "rank", "id", "rung", to_string(setup.objective),
              "ate_pct");
  if (show_x) std::printf(" %-10s", "disagree%");
  for (const auto& prm : setup.params) std::printf(" %s", prm.name.c_str());
  std::printf("\n");
  for (size_t k = 0; k < rank.size(); ++k) {
    const auto& c = out.candidates[rank[k]];
    // Mean of a field over the sequences when every one has it.
    const auto mean_of = [&c](std::optional<double> SeqResult::*field) -> std::optional<double> {
      double sum = 0;
      for (const auto& r : c.results) {
        if (!(r.*field)) return std::nullopt;
        sum += *(r.*field);
      }
      if (c.results.empty()) return std::nullopt;
      return sum / static_cast<double>(c.results.size());
    };
    std::printf("%-4zu %-5d %-5d %-10.4f %-10s", k + 1, c.candidate.id, c.rung + 1, c.objective,
                fmt_opt(mean_of(&SeqResult::ate_pct), "%.4f").c_str());
    if (show_x)
      std::printf(" %-10s", fmt_opt(mean_of(&SeqResult::disagreement_pct), "%.4f").c_str());
    for (size_t i = 0; i < setup.params.size(); ++i) {
      std::printf(" %s", format_tune_value(setup.params[i], c.candidate.values[i]).c_str());
    }
    std::printf("%s\n", c.candidate.id == 0 ? "  (start)" : "");
  }
  std::printf("influence (|Spearman| of parameter vs rung-1 objective):");
  for (size_t i : order) std::printf(" %s %.2f", setup.params[i].name.c_str(), influence[i]);
  std::printf("\n");
  // With ground truth, how the consistency objective ranks the rung-1 candidates against ATE.
  {
    std::vector<double> a, c;  // rung-0 scores of every candidate
    for (const auto& cs : out.candidates) {
      a.push_back(mean_score(TuneObjective::kAte, cs.rung0_results));
      c.push_back(mean_score(TuneObjective::kConsistency, cs.rung0_results));
    }
    const double tau = kendall_tau(a, c);
    const size_t best_a = static_cast<size_t>(std::min_element(a.begin(), a.end()) - a.begin());
    const size_t best_c = static_cast<size_t>(std::min_element(c.begin(), c.end()) - c.begin());
    bool any_gt = false;
    for (double v : a) any_gt = any_gt || v < kFailureScore;
    if (any_gt) {
      std::printf(
          "rank agreement, rung 1 (consistency vs ate objective, %zu configurations): Spearman "
          "%.2f, Kendall %.2f, same best: %s (ate objective of the consistency best %.4f, of the "
          "ate best %.4f); same order (docs/tune.md: that best within 10%% and Kendall above "
          "0.6): %s\n",
          a.size(), spearman(a, c), tau, best_a == best_c ? "yes" : "no", a[best_c], a[best_a],
          a[best_c] <= 1.1 * a[best_a] && tau > 0.6 ? "yes" : "no");
    }
  }
  if (!out.holdout.empty()) {
    std::printf("\nholdout (never searched; %s):\n",
                setup.plan.frames.back() > 0
                    ? (std::to_string(setup.plan.frames.back()) + " frames").c_str()
                    : "all frames");
    std::printf("%-9s %-10s", "config", to_string(setup.objective));
    for (const auto& s : holdout) std::printf(" | %s ate%% tracked", s.c_str());
    std::printf("\n");
    for (const auto& h : out.holdout) {
      std::printf("%-9s %-10.4f", h.label.c_str(), h.objective);
      for (const auto& r : h.results) {
        std::printf(" | %s %.3f", fmt_opt(r.ate_pct).c_str(), r.tracked_ratio);
      }
      std::printf("\n");
    }
  }

  // best.yaml: the base configuration with the best values.
  const CandidateScore& best = out.candidates[static_cast<size_t>(out.best)];
  std::vector<std::string> sets = base_sets;
  for (const auto& o : candidate_overrides(setup.params, best.candidate)) sets.push_back(o);
  AppConfig best_cfg = load_cli_config(config_path, sets);
  char header[512];
  std::snprintf(header, sizeof(header),
                "# rdslam tune: best of %zu configurations (id %d), %s objective %.4f at rung %d;"
                "\n# base: %s; only keys that differ from the built-in defaults.\n",
                out.candidates.size(), best.candidate.id, to_string(setup.objective),
                best.objective, best.rung + 1,
                config_path.empty() ? "defaults" : config_path.c_str());
  write_best_yaml(best_path, header, best_cfg);
  load_config(best_path, {});  // what we wrote must load (throws ConfigError otherwise)
  write_plot(setup, out, order, influence, plot_path);
  std::printf("\nbest: %s (id %d)\nwrote %s, %s\n", to_string(setup.objective), best.candidate.id,
              best_path.c_str(), plot_path.c_str());
  return 0;
}

}  // namespace rdslam
