// The search behind `rdslam tune` (firmware_app/tune.h) without processes: the parameter-file
// parser and its messages, the deterministic sampler, the successive-halving plan, the
// objective formula with its cross-configuration disagreement term, rank correlations, and the
// search loop with a fake evaluator: determinism, halving, holdout rows and resuming from
// results.jsonl.
#include "firmware_app/tune.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>

#include "firmware_app/config.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;

std::string error_of(const std::string& yaml) {
  try {
    parse_tune_params(yaml, "t.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(TuneParams, ParsesTheExampleFile) {
  const auto ps = load_tune_params(std::string(RDSLAM_SOURCE_DIR) + "/docs/tune/example.yaml");
  ASSERT_EQ(ps.size(), 4u);
  EXPECT_EQ(ps[0].name, "parsac.inlier_threshold_px");
  EXPECT_TRUE(ps[0].log_scale);
  EXPECT_FALSE(ps[0].integer);
  EXPECT_EQ(ps[2].name, "tracker.max_keyframe_interval");
  EXPECT_TRUE(ps[2].integer);
  EXPECT_DOUBLE_EQ(ps[2].min, 5.0);
  EXPECT_DOUBLE_EQ(ps[2].max, 80.0);
}

// The parameter files and deliberately bad starts of docs/tune.md's studies: every shipped
// parameter file parses, and every bad start is a configuration `rdslam config` accepts that
// sets each key of its study's parameter file away from the built-in default.
TEST(TuneParams, TheStudiesFilesLoadAndTheirBadStartsDifferFromTheDefaults) {
  const std::string dir = std::string(RDSLAM_SOURCE_DIR) + "/docs/tune/";
  EXPECT_EQ(load_tune_params(dir + "rank_study.yaml").size(), 4u);
  const std::pair<const char*, const char*> studies[] = {
      {"example.yaml", "bad_start.yaml"}, {"keyframes.yaml", "bad_start_keyframes.yaml"}};
  AppConfig defaults = load_config("", {});
  for (const auto& [params_file, start_file] : studies) {
    SCOPED_TRACE(start_file);
    const auto ps = load_tune_params(dir + params_file);
    ASSERT_FALSE(ps.empty());
    AppConfig start = load_config(dir + start_file, {});
    const auto a = tune_start_values(defaults, ps), b = tune_start_values(start, ps);
    ASSERT_EQ(a.size(), ps.size());
    ASSERT_EQ(b.size(), ps.size());
    for (size_t i = 0; i < ps.size(); ++i) {
      EXPECT_NE(a[i], b[i]) << ps[i].name << " is not set away from its default";
      EXPECT_GE(b[i], ps[i].min) << ps[i].name;
      EXPECT_LE(b[i], ps[i].max) << ps[i].name;
    }
  }
}

TEST(TuneParams, DefaultsScaleLinearAndTypeFromTheKey) {
  const auto ps = parse_tune_params(
      "- {name: tracker.m1, min: 40, max: 200}\n- {name: dynamic.tau_c, min: 5, max: 50}\n", "t");
  ASSERT_EQ(ps.size(), 2u);
  EXPECT_TRUE(ps[0].integer);
  EXPECT_FALSE(ps[0].log_scale);
  EXPECT_FALSE(ps[1].integer);
}

TEST(TuneParams, ErrorsNameTheKey) {
  const std::pair<const char*, const char*> cases[] = {
      {"- {name: tracker.no_such_key, min: 1, max: 2}",
       "tracker.no_such_key: unknown configuration key"},
      {"- {name: dynamic.tau_c, min: 30, max: 30}", "dynamic.tau_c: min 30 >= max 30"},
      {"- {name: dynamic.histogram_threshold, min: 0, max: 1, scale: log}",
       "dynamic.histogram_threshold: log scale needs min > 0"},
      {"- {name: tracker.m1, min: 40, max: 200, type: float}",
       "tracker.m1: type: float, but the configuration key is an integer"},
      {"- {name: matching.orb_local_ratio, min: 0.5, max: 7}",
       "matching.orb_local_ratio: range [0.5, 7] is outside"},
      {"- {name: tracker.robust_per_frame, min: 0, max: 1}",
       "tracker.robust_per_frame: not a numeric configuration key"},
      {"- {name: tracker.m1, min: 40, max: 90}\n- {name: tracker.m1, min: 50, max: 60}",
       "tracker.m1: listed twice"},
      {"- {name: tracker.m1, min: 40, max: 90, step: 2}", "unknown field 'step'"},
      {"- {name: tracker.m1, min: 40.5, max: 90}",
       "tracker.m1: type int needs integer min and max"},
      {"- {name: tracker.m1, min: 40, max: 90, scale: cubic}",
       "tracker.m1: scale: 'cubic' is not linear or log"},
      {"name: tracker.m1", "expected a non-empty list"},
      {"- {name: tracker.m1, min: x, max: 90}", "tracker.m1: min: 'x' is not a number"},
  };
  for (const auto& [yaml, expected] : cases) {
    const std::string e = error_of(yaml);
    EXPECT_NE(e.find(expected), std::string::npos) << yaml << " -> " << e;
    EXPECT_EQ(e.rfind("tune params t.yaml: ", 0), 0u) << e;  // names the file
  }
}

std::vector<TuneParam> two_params() {
  return parse_tune_params(
      "- {name: parsac.inlier_threshold_px, min: 0.5, max: 12, scale: log}\n"
      "- {name: tracker.max_keyframe_interval, min: 5, max: 80}\n",
      "t");
}

TEST(TuneSampler, DeterministicInRangeAndStartFirst) {
  const auto ps = two_params();
  const auto a = sample_candidates(ps, {3.0, 200.0}, 50, 42);
  const auto b = sample_candidates(ps, {3.0, 200.0}, 50, 42);
  const auto c = sample_candidates(ps, {3.0, 200.0}, 50, 43);
  ASSERT_EQ(a.size(), 50u);
  EXPECT_DOUBLE_EQ(a[0].values[0], 3.0);
  EXPECT_DOUBLE_EQ(a[0].values[1], 80.0);  // the start, clamped into the range
  bool differs = false;
  int below_geometric_mean = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].values, b[i].values);
    differs = differs || a[i].values != c[i].values;
    EXPECT_GE(a[i].values[0], 0.5);
    EXPECT_LE(a[i].values[0], 12.0);
    EXPECT_EQ(a[i].values[1], std::round(a[i].values[1]));
    EXPECT_GE(a[i].values[1], 5.0);
    EXPECT_LE(a[i].values[1], 80.0);
    if (i > 0 && a[i].values[0] < std::sqrt(0.5 * 12.0)) ++below_geometric_mean;
  }
  EXPECT_TRUE(differs);
  // Log scale: about half of the draws below the geometric mean (49 draws; loose bounds).
  EXPECT_GT(below_geometric_mean, 12);
  EXPECT_LT(below_geometric_mean, 37);
  const auto ov = candidate_overrides(ps, a[0]);
  ASSERT_EQ(ov.size(), 2u);
  EXPECT_EQ(ov[0], "parsac.inlier_threshold_px=3");
  EXPECT_EQ(ov[1], "tracker.max_keyframe_interval=80");
}

TEST(TunePlan, HalvingFitsTheBudget) {
  const HalvingPlan p = plan_halving(24, 2, 120);
  EXPECT_EQ(p.configs, (std::vector<int>{18, 6}));
  EXPECT_EQ(p.frames, (std::vector<int>{40, 120}));
  EXPECT_LE(p.evaluations(), 24);
  const HalvingPlan q = plan_halving(40, 3, 270);
  EXPECT_EQ(q.configs, (std::vector<int>{28, 9, 3}));
  EXPECT_EQ(q.frames, (std::vector<int>{30, 90, 270}));
  const HalvingPlan flat = plan_halving(5, 1, 0);
  EXPECT_EQ(flat.configs, (std::vector<int>{5}));
  EXPECT_EQ(flat.frames, (std::vector<int>{0}));
  EXPECT_THROW(plan_halving(10, 2, 0), std::invalid_argument);
  EXPECT_THROW(plan_halving(1, 1, 0), std::invalid_argument);
}

TEST(TuneObjective, ScoreFormula) {
  SeqResult r;
  EXPECT_EQ(sequence_score(TuneObjective::kAte, r), kFailureScore);  // did not run
  r.ok = true;
  EXPECT_EQ(sequence_score(TuneObjective::kAte, r), kFailureScore);  // never initialized
  r.initialized = true;
  r.tracked_ratio_after_init = 1.0;
  EXPECT_EQ(sequence_score(TuneObjective::kAte, r), kFailureScore);  // no ATE
  r.ate_pct = 0.5;
  r.consistency_pct = 0.2;
  EXPECT_DOUBLE_EQ(sequence_score(TuneObjective::kAte, r), 0.5);
  EXPECT_EQ(sequence_score(TuneObjective::kConsistency, r), kFailureScore);  // no roughness
  r.roughness_pct = 0.05;
  EXPECT_DOUBLE_EQ(sequence_score(TuneObjective::kConsistency, r), 0.25);
  r.tracked_ratio_after_init = 0.75;  // 20 points short of 95%: + 0.1 * 20
  EXPECT_NEAR(sequence_score(TuneObjective::kAte, r), 2.5, 1e-12);
}

TEST(TuneRanks, SpearmanAndKendall) {
  const std::vector<double> a = {1, 2, 3, 4, 5};
  EXPECT_NEAR(spearman(a, {10, 20, 30, 40, 50}), 1.0, 1e-12);
  EXPECT_NEAR(spearman(a, {5, 4, 3, 2, 1}), -1.0, 1e-12);
  EXPECT_NEAR(kendall_tau(a, {1, 3, 2, 4, 5}), 0.8, 1e-12);  // 9 concordant, 1 discordant
  // Spearman of {1,2,3,4,5} vs {1,3,2,4,5}: 1 - 6 * 2 / (5 * 24) = 0.9
  EXPECT_NEAR(spearman(a, {1, 3, 2, 4, 5}), 0.9, 1e-12);
  EXPECT_EQ(spearman(a, {1, 1, 1, 1, 1}), 0.0);
}

TEST(TuneObjective, Roughness) {
  // A straight line at constant speed: no roughness; path 4 m.
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 5; ++i) line.emplace_back(i, 0, 0);
  ASSERT_TRUE(trajectory_roughness_pct(line).has_value());
  EXPECT_NEAR(*trajectory_roughness_pct(line), 0.0, 1e-12);
  // One position 0.1 m off: second differences 0.1, 0.2, 0.1 (m) over 3 triples; the path
  // grows to 2 + 2 * sqrt(1.01).
  line[2].y() = 0.1;
  const double path = 2.0 + 2.0 * std::sqrt(1.01);
  EXPECT_NEAR(*trajectory_roughness_pct(line), 100.0 * std::sqrt(0.06 / 3.0) / path, 1e-12);
  // Scale-free: the same path 10 times larger has the same roughness.
  std::vector<Eigen::Vector3d> big;
  for (const auto& p : line) big.push_back(10.0 * p);
  EXPECT_NEAR(*trajectory_roughness_pct(big), *trajectory_roughness_pct(line), 1e-12);
  EXPECT_FALSE(trajectory_roughness_pct({line[0], line[1]}).has_value());
}

// A curved path of n poses, 0.1 s apart, with position noise `wobble` (m) of a fixed pattern
// whose phase is `phase` (different phases: independent-looking errors).
Trajectory path(int n, double wobble = 0.0, int phase = 0) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    StampedPose p;
    p.stamp_ns = 100000000LL * i;
    const double s = 0.1 * i;
    p.p_world_cam = Eigen::Vector3d(s, std::sin(s), 0.1 * s * s);
    p.p_world_cam += wobble * Eigen::Vector3d(std::sin(1.7 * (i + phase)),
                                              std::cos(2.3 * (i + 3 * phase)), std::sin(0.9 * i));
    t.push_back(p);
  }
  return t;
}

TEST(TuneObjective, TrajectoryDistanceIsSim3InvariantAndSymmetric) {
  const Trajectory a = path(40);
  Trajectory b = a;  // the same path in another frame and scale: no disagreement
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  for (auto& p : b) p.p_world_cam = 3.0 * (q * p.p_world_cam) + Eigen::Vector3d(5, -1, 2);
  ASSERT_TRUE(trajectory_distance_pct(a, b).has_value());
  EXPECT_NEAR(*trajectory_distance_pct(a, b), 0.0, 1e-9);
  const Trajectory c = path(40, 0.05, 1);
  ASSERT_TRUE(trajectory_distance_pct(a, c).has_value());
  EXPECT_GT(*trajectory_distance_pct(a, c), 0.1);
  EXPECT_NEAR(*trajectory_distance_pct(a, c), *trajectory_distance_pct(c, a), 1e-12);
  // Only 2 common stamps: no distance.
  Trajectory late = path(40);
  for (auto& p : late) p.stamp_ns += 100000000LL * 38;
  EXPECT_FALSE(trajectory_distance_pct(a, late).has_value());
  // A non-finite position (a corrupt file): no distance, never a NaN in an objective.
  Trajectory bad = path(40);
  bad[7].p_world_cam.x() = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(trajectory_distance_pct(a, bad).has_value());
}

TEST(TuneObjective, DisagreementIsTheMedianDistanceToTheOtherPeers) {
  // Three runs near the truth, one far from it (a pose following something else), one
  // without a trajectory.
  const Trajectory g1 = path(60, 0.01, 0), g2 = path(60, 0.01, 5), g3 = path(60, 0.01, 11);
  Trajectory far = path(60, 0.01, 17);
  for (size_t i = 30; i < far.size(); ++i) far[i].p_world_cam.z() += 0.05 * (i - 30.0);
  const std::vector<const Trajectory*> runs = {&g1, &g2, &g3, &far, nullptr};
  const auto d = [](const Trajectory& x, const Trajectory& y) {
    return *trajectory_distance_pct(x, y);
  };
  const auto median3 = [](double a, double b, double c) {
    return std::max(std::min(a, b), std::min(std::max(a, b), c));
  };
  {
    const auto x = tune_disagreement_pct(runs, {true, true, true, true, false});
    ASSERT_EQ(x.size(), 5u);
    ASSERT_TRUE(x[0] && x[1] && x[2] && x[3]);
    EXPECT_FALSE(x[4].has_value());
    EXPECT_NEAR(*x[0], median3(d(g1, g2), d(g1, g3), d(g1, far)), 1e-12);
    EXPECT_NEAR(*x[3], median3(d(far, g1), d(far, g2), d(far, g3)), 1e-12);
    for (int i = 0; i < 3; ++i) EXPECT_LT(2.0 * *x[i], *x[3]);
  }
  {
    // The far run did not track the sequence: it is no peer, so the others compare among
    // themselves only (median of two = their mean), and it is compared with them.
    const auto x = tune_disagreement_pct(runs, {true, true, true, false, false});
    EXPECT_NEAR(*x[0], 0.5 * (d(g1, g2) + d(g1, g3)), 1e-12);
    EXPECT_NEAR(*x[3], median3(d(far, g1), d(far, g2), d(far, g3)), 1e-12);
  }
  {
    // One peer: it has no other peer (0); everyone else is compared with it.
    const auto x = tune_disagreement_pct(runs, {false, true, false, false, false});
    EXPECT_EQ(*x[1], 0.0);
    EXPECT_NEAR(*x[0], d(g1, g2), 1e-12);
  }
  EXPECT_THROW(tune_disagreement_pct(runs, {true}), std::invalid_argument);
}

// A fake pipeline: the score is a smooth function of the overrides (best near threshold 2,
// keyframe interval 20), shorter runs are noisier but keep the order; counts the runs.
struct FakeEval {
  int* calls;
  SeqResult result(const EvalRequest& q) const {
    double th = 0, kf = 0;
    for (const auto& o : q.overrides) {
      const double v = std::stod(o.substr(o.find('=') + 1));
      if (o.rfind("parsac.", 0) == 0) th = v;
      if (o.rfind("tracker.", 0) == 0) kf = v;
    }
    SeqResult r;
    r.ok = r.initialized = true;
    r.tracked_ratio = r.tracked_ratio_after_init = 1.0;
    const double seq = q.sequence == "synth:a" ? 0.1 : 0.2;
    r.ate_pct = seq + std::pow(std::log(th / 2.0), 2) + 0.001 * std::fabs(kf - 20) +
                (q.frames < 90 ? 0.01 : 0.0);
    r.consistency_pct = 0.5 * *r.ate_pct;
    r.roughness_pct = 0.1 * *r.ate_pct;
    return r;
  }
  void operator()(const std::vector<EvalRequest>& reqs,
                  const std::function<void(size_t, const SeqResult&)>& done) const {
    for (size_t i = reqs.size(); i-- > 0;) {  // out of order, as parallel children finish
      ++*calls;
      done(i, result(reqs[i]));
    }
  }
};

TuneSetup fake_setup() {
  TuneSetup s;
  s.params = two_params();
  s.start = {12.0, 80.0};
  s.sequences = {"synth:a", "synth:b"};
  s.holdout = {"synth:c"};
  s.plan = plan_halving(12, 2, 90);  // 9 configs at 30 frames, 3 at 90
  s.seed = 5;
  s.base_identity = "base";
  return s;
}

struct TempDir {
  fs::path path;
  TempDir() {
    path =
        fs::temp_directory_path() /
        ("rdslam-tune-test-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

TEST(TuneSearch, DeterministicHalvingAndHoldout) {
  TempDir d1, d2;
  int calls1 = 0, calls2 = 0;
  ResultStore s1((d1.path / "r1.jsonl").string()), s2((d1.path / "r2.jsonl").string());
  const TuneSetup setup = fake_setup();
  const TuneOutcome a = run_tune(setup, FakeEval{&calls1}, s1, nullptr);
  const TuneOutcome b = run_tune(setup, FakeEval{&calls2}, s2, nullptr);
  EXPECT_EQ(calls1, 9 * 2 + 3 * 2 + 3 * 1);  // rung 1, rung 2, holdout (defaults, start, best)
  EXPECT_EQ(calls1, calls2);
  ASSERT_EQ(a.candidates.size(), 9u);
  EXPECT_EQ(a.best, b.best);
  for (size_t i = 0; i < a.candidates.size(); ++i) {
    EXPECT_EQ(a.candidates[i].candidate.values, b.candidates[i].candidate.values);
    EXPECT_EQ(a.candidates[i].objective, b.candidates[i].objective);
  }
  // The best is the rung-2 candidate with the lowest objective, and no rung-1-only candidate
  // beats the promoted ones at rung 1.
  int promoted = 0;
  double worst_promoted_rung0 = 0, best_dropped_rung0 = 1e300;
  for (const auto& c : a.candidates) {
    if (c.rung == 1) {
      ++promoted;
      worst_promoted_rung0 = std::max(worst_promoted_rung0, c.rung0_objective);
      EXPECT_LE(a.candidates[a.best].objective, c.objective);
    } else {
      best_dropped_rung0 = std::min(best_dropped_rung0, c.rung0_objective);
    }
  }
  EXPECT_EQ(promoted, 3);
  EXPECT_LE(worst_promoted_rung0, best_dropped_rung0);
  // The bad start (threshold 12) is beaten.
  EXPECT_LT(a.candidates[a.best].objective, a.candidates[0].rung0_objective);
  ASSERT_EQ(a.holdout.size(), 3u);
  EXPECT_EQ(a.holdout[0].label, "defaults");
  EXPECT_EQ(a.holdout[2].label, "best");
  EXPECT_LT(a.holdout[2].objective, a.holdout[1].objective);
}

// FakeEval that also leaves an online trajectory per run: the path with an error of the run's
// ATE size, of a pattern set by the run key (different configurations err differently).
struct FakeEvalWithTrajectories {
  FakeEval fake;
  std::map<std::string, Trajectory>* trajectories;
  void operator()(const std::vector<EvalRequest>& reqs,
                  const std::function<void(size_t, const SeqResult&)>& done) const {
    fake(reqs, [&](size_t i, const SeqResult& r) {
      const int phase = static_cast<int>(std::stoull(reqs[i].key.substr(0, 6), nullptr, 16) % 97);
      (*trajectories)[reqs[i].key] = path(50, 0.01 * *r.ate_pct, phase);
      done(i, r);
    });
  }
};

TEST(TuneSearch, ConsistencyComparesTheConfigurationsOfOneRung) {
  TempDir d;
  ResultStore store((d.path / "results.jsonl").string());
  TuneSetup setup = fake_setup();
  setup.objective = TuneObjective::kConsistency;
  std::map<std::string, Trajectory> trajectories;
  setup.online_trajectory = [&](const std::string& key) {
    const auto it = trajectories.find(key);
    return it == trajectories.end() ? Trajectory{} : it->second;
  };
  int calls = 0;
  const TuneOutcome out =
      run_tune(setup, FakeEvalWithTrajectories{FakeEval{&calls}, &trajectories}, store, nullptr);
  ASSERT_EQ(out.candidates.size(), 9u);
  size_t lo = 0, hi = 0;  // the candidates with the lowest and highest rung-0 ATE
  for (size_t i = 0; i < out.candidates.size(); ++i) {
    const CandidateScore& c = out.candidates[i];
    ASSERT_EQ(c.rung0_results.size(), 2u);
    double sum = 0.0;
    for (const auto& r : c.rung0_results) {
      ASSERT_TRUE(r.disagreement_pct.has_value());
      EXPECT_GT(*r.disagreement_pct, 0.0);
      sum += *r.consistency_pct + *r.roughness_pct + *r.disagreement_pct;
    }
    EXPECT_NEAR(c.rung0_objective, sum / 2.0, 1e-12);
    const double ate = *c.rung0_results[0].ate_pct;
    if (ate < *out.candidates[lo].rung0_results[0].ate_pct) lo = i;
    if (ate > *out.candidates[hi].rung0_results[0].ate_pct) hi = i;
  }
  // A larger error is further from the other configurations.
  EXPECT_LT(*out.candidates[lo].rung0_results[0].disagreement_pct,
            *out.candidates[hi].rung0_results[0].disagreement_pct);
  // Without trajectories the term is not computed and counts 0.
  TempDir d2;
  ResultStore store2((d2.path / "results.jsonl").string());
  setup.online_trajectory = nullptr;
  int calls2 = 0;
  const TuneOutcome plain = run_tune(setup, FakeEval{&calls2}, store2, nullptr);
  for (const auto& c : plain.candidates) {
    EXPECT_FALSE(c.rung0_results[0].disagreement_pct.has_value());
  }
  ASSERT_EQ(out.holdout.size(), 3u);
  for (const auto& h : out.holdout) EXPECT_TRUE(h.results[0].disagreement_pct.has_value());
}

TEST(TuneSearch, ResumesFromTheResultsFile) {
  TempDir d;
  const std::string path = (d.path / "results.jsonl").string();
  const TuneSetup setup = fake_setup();
  int full_calls = 0;
  TuneOutcome full;
  {
    ResultStore store(path);
    full = run_tune(setup, FakeEval{&full_calls}, store, nullptr);
  }
  // Everything done: a restart runs nothing and finds the same best.
  {
    int calls = 0;
    ResultStore store(path);
    EXPECT_EQ(store.loaded(), static_cast<size_t>(full_calls));
    const TuneOutcome again = run_tune(setup, FakeEval{&calls}, store, nullptr);
    EXPECT_EQ(calls, 0);
    EXPECT_EQ(again.best, full.best);
    EXPECT_EQ(again.runs_resumed, again.runs_total);
  }
  // Killed after 7 runs, in the middle of writing the 8th line: a restart runs the rest only.
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  in.close();
  {
    std::ofstream out(path, std::ios::trunc);
    for (int i = 0; i < 7; ++i) out << lines[static_cast<size_t>(i)] << "\n";
    out << lines[7].substr(0, lines[7].size() / 2);  // no newline: cut short
  }
  int calls = 0;
  ResultStore store(path);
  EXPECT_EQ(store.loaded(), 7u);
  // The cut line has no newline: the next append must start on a new line to stay parseable.
  const TuneOutcome resumed = run_tune(setup, FakeEval{&calls}, store, nullptr);
  EXPECT_EQ(calls, full_calls - 7);
  EXPECT_EQ(resumed.best, full.best);
  EXPECT_EQ(resumed.candidates[static_cast<size_t>(resumed.best)].objective,
            full.candidates[static_cast<size_t>(full.best)].objective);
  ResultStore reread(path);
  EXPECT_EQ(reread.loaded(), static_cast<size_t>(full_calls));
}

}  // namespace
}  // namespace rdslam
