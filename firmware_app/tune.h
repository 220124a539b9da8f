// `rdslam tune` (issue 27; docs/tune.md): a search of configuration thresholds per environment.
// This module holds what does not start processes: the parameter file (which config keys to
// search, their ranges and scales), the deterministic candidate sampler, the successive-halving
// plan, the objectives computed from one replay's results, the resumable results file
// (OUT_DIR/results.jsonl) and the search loop itself, which asks an Evaluator for the runs it
// needs. firmware_app/cmd_tune.cpp supplies the Evaluator that starts `rdslam replay` children.
//
// Ownership: values; ResultStore owns its file name and an in-memory index. Threads: the
// thread that runs the tune command (main); an Evaluator may use processes, not threads of ours.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/trajectory.h"

namespace rdslam {

// One searched parameter: a numeric config key as `rdslam config` prints it (section.key).
struct TuneParam {
  std::string name;
  double min = 0.0;
  double max = 0.0;
  bool log_scale = false;  // scale: log (sampled uniformly in log(value))
  bool integer = false;    // type: int (values rounded to integers)
};

// Parses the parameter file's text (a YAML list of {name, min, max, scale, type}). Every key
// is checked against the configuration: unknown key, non-numeric key, float type on an integer
// key, min >= max, a range outside the key's allowed range, log scale with min <= 0, integer
// bounds that are not integers, duplicates. Throws ConfigError naming `where` and the key.
std::vector<TuneParam> parse_tune_params(const std::string& yaml_text, const std::string& where);
// Reads and parses a file (ConfigError when it cannot be read).
std::vector<TuneParam> load_tune_params(const std::string& path);

// The current values of `params` in a configuration (the search's start, candidate 0).
struct AppConfig;
std::vector<double> tune_start_values(AppConfig& cfg, const std::vector<TuneParam>& params);

// The value as written into --set and best.yaml: an integer for int parameters, else %.6g.
std::string format_tune_value(const TuneParam& p, double v);

// A configuration of the searched parameters, in the order of the parameter list.
struct TuneCandidate {
  int id = 0;  // 0: the start configuration (the base config's own values, clamped to range)
  std::vector<double> values;
};
// Candidate 0 holds `start` (clamped into the ranges, rounded for integers); candidates 1..n-1
// are drawn uniformly (in log space for log-scale parameters) from a 64-bit Mersenne twister
// seeded with `seed`, so the list depends only on (params, start, n, seed).
std::vector<TuneCandidate> sample_candidates(const std::vector<TuneParam>& params,
                                             const std::vector<double>& start, int n,
                                             uint64_t seed);
// "key=value" overrides of a candidate.
std::vector<std::string> candidate_overrides(const std::vector<TuneParam>& params,
                                             const TuneCandidate& c);

// Successive halving with reduction factor eta over frame counts: rung r evaluates
// configs[r] configurations on the first frames[r] frames of every search sequence (0: all
// frames); the best 1/eta of a rung go on to the next. `budget` bounds the sum of configs[]
// (a configuration evaluation = one configuration on all search sequences at one rung).
struct HalvingPlan {
  std::vector<int> configs;
  std::vector<int> frames;
  int evaluations() const;
};
// `rungs` >= 1; frames[last] = `frames` and frames[r] = frames / eta^(last - r) (at least
// `min_frames`); with frames = 0 (full sequences) rungs must be 1. Throws std::invalid_argument
// naming the option when the budget cannot hold the plan (fewer than 2 configurations at rung 0).
HalvingPlan plan_halving(int budget, int rungs, int frames, int eta = 3, int min_frames = 20);

// What one replay of one sequence gave (from its report and trajectories).
struct SeqResult {
  bool ok = false;  // the replay ran and wrote its report
  std::string error;
  bool initialized = false;  // initialized_frame >= 0
  double tracked_ratio = 0.0;
  double tracked_ratio_after_init = 0.0;
  std::optional<double> ate_pct;          // online ATE, % of path (needs ground truth)
  std::optional<double> ate_final_pct;    // final (bundle-adjusted) trajectory's ATE, % of path
  std::optional<double> consistency_pct;  // online vs final, Sim3-aligned RMS, % of final path
  std::optional<double> roughness_pct;  // online trajectory's roughness (trajectory_roughness_pct)
  double wall_s = 0.0;
  // Disagreement with the other configurations run on the same sequence at the same frame count
  // (tune_disagreement_pct): set by run_tune, not stored in the results file (it depends on
  // which runs are compared). Empty: not computed, or the run has no trajectory.
  std::optional<double> disagreement_pct;
};

enum class TuneObjective { kAte, kConsistency };
bool parse_tune_objective(const std::string& text, TuneObjective& out);
const char* to_string(TuneObjective o);

// The per-sequence score (lower is better; docs/tune.md "Objectives"):
//   failed run, never initialized, or no error term:   kFailureScore
//   else: E + kTrackedWeight * 100 * max(0, kMinTracked - tracked_ratio_after_init)
// with E = ate_pct (ate) or consistency_pct + roughness_pct + disagreement_pct (consistency;
// disagreement counts 0 when empty). An objective is the mean over the sequences.
constexpr double kFailureScore = 100.0;
constexpr double kMinTracked = 0.95;
constexpr double kTrackedWeight = 0.1;
double sequence_score(TuneObjective o, const SeqResult& r);
// The objective of a configuration: the mean of sequence_score over its sequences
// (kFailureScore when there are none).
double mean_score(TuneObjective o, const std::vector<SeqResult>& rs);

// Roughness of a trajectory without ground truth: the RMS of the second differences of the
// consecutive positions (p[i+1] - 2 p[i] + p[i-1]) in % of the path length (sum of the steps):
// tracking noise makes a camera path jagged; scale-free like ATE % of path. Empty for fewer
// than 3 positions or a zero path.
std::optional<double> trajectory_roughness_pct(const std::vector<Eigen::Vector3d>& positions);

// Symmetric distance of two trajectories of the same sequence: the Sim(3)-aligned RMS of one
// against the other on their common stamps in % of the other's path, averaged over both
// directions. Empty when they share fewer than 3 stamps, an alignment is degenerate or the
// result is not finite.
std::optional<double> trajectory_distance_pct(const Trajectory& a, const Trajectory& b);

// The consistency objective's cross-configuration term (docs/tune.md "Objectives"). `runs`:
// the online trajectories of the configurations evaluated together on one sequence (nullptr
// or fewer than 3 poses: no trajectory); `peer[i]`: run i tracked the sequence (at least
// kMinTracked of its frames after initialization). Per run with a trajectory: the median of
// its distances (trajectory_distance_pct) to the *other* peers, 0 when it has none; empty for
// runs without a trajectory. Configurations that track a sequence well agree closely with each
// other; a run whose poses follow a moving object or drift is far from them.
std::vector<std::optional<double>> tune_disagreement_pct(const std::vector<const Trajectory*>& runs,
                                                         const std::vector<bool>& peer);

// Resumable results: one JSON object per line, keyed by a hash of everything that determines
// the run (base configuration, sequence, frames, overrides). Lines that do not parse (a run
// killed while writing) are ignored.
class ResultStore {
 public:
  explicit ResultStore(std::string path);  // loads the existing lines, if any
  const SeqResult* find(const std::string& key) const;
  // Appends the line (and flushes) and indexes it. Throws std::runtime_error when the file
  // cannot be written.
  void append(const std::string& key, const std::string& sequence, int frames,
              const std::vector<std::string>& overrides, const SeqResult& r);
  size_t loaded() const { return loaded_; }  // lines read at construction

 private:
  std::string path_;
  std::map<std::string, SeqResult> index_;
  size_t loaded_ = 0;
  bool need_newline_ = false;  // the file ends in a line cut short (a kill while writing)
};

// 16 hex digits (FNV-1a 64) of the run's identity.
std::string run_key(const std::string& base_identity, const std::string& sequence, int frames,
                    const std::vector<std::string>& overrides);

// One replay the search needs.
struct EvalRequest {
  std::string key;
  std::string sequence;
  int frames = 0;  // 0: the whole sequence
  std::vector<std::string> overrides;
  bool use_base_config = true;  // false: the built-in defaults (holdout comparison)
};
// Runs the requests (in any order, in parallel if it likes) and calls `done(i, result)` on the
// calling thread as each request i finishes (the search appends it to the results file at
// once, so a killed tune loses only the runs in flight).
using Evaluator = std::function<void(const std::vector<EvalRequest>&,
                                     const std::function<void(size_t, const SeqResult&)>& done)>;

struct TuneSetup {
  std::vector<TuneParam> params;
  std::vector<double> start;  // the base configuration's values of params
  std::vector<std::string> sequences;
  std::vector<std::string> holdout;
  TuneObjective objective = TuneObjective::kAte;
  HalvingPlan plan;
  uint64_t seed = 1;
  std::string base_identity;  // the base configuration (dump), part of every run key
  // A finished run's online trajectory by run key (empty when it has none); without it the
  // disagreement term is not computed (counts 0 in the consistency objective).
  std::function<Trajectory(const std::string& key)> online_trajectory;
};

struct CandidateScore {
  TuneCandidate candidate;
  int rung = 0;                            // highest rung reached
  double objective = kFailureScore;        // at that rung
  std::vector<SeqResult> results;          // per search sequence, at that rung
  double rung0_objective = kFailureScore;  // at rung 0 (every candidate has one; the plot)
  std::vector<SeqResult> rung0_results;    // per search sequence, at rung 0
};

struct HoldoutRow {
  std::string label;  // "defaults", "start", "best"
  double objective = kFailureScore;
  std::vector<SeqResult> results;  // per holdout sequence
};

struct TuneOutcome {
  std::vector<CandidateScore> candidates;  // all sampled, by id
  int best = 0;                            // index into candidates
  std::vector<HoldoutRow> holdout;         // empty without holdout sequences
  int runs_total = 0;                      // distinct replays needed
  int runs_resumed = 0;                    // of them, found in the results file
};

// Progress: (finished runs, runs of the current batch, what the batch is).
using TuneProgress = std::function<void(size_t, size_t, const std::string&)>;

// The search: rung by rung, only the runs not in `store` go to `eval`; each finished run is
// appended to `store` before the next batch starts. Deterministic for a given setup (ties are
// broken by candidate id). Holdout rows: the built-in defaults, the start and the best
// candidate on the holdout sequences at the last rung's frame count. The disagreement term is
// computed per sequence among the runs of one rung (or among the holdout rows).
TuneOutcome run_tune(const TuneSetup& setup, const Evaluator& eval, ResultStore& store,
                     const TuneProgress& progress);

// Spearman rank correlation (average ranks for ties) and Kendall tau-b of two equally long
// series; 0 when undefined (fewer than 2 values or a constant series).
double spearman(const std::vector<double>& a, const std::vector<double>& b);
double kendall_tau(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace rdslam
