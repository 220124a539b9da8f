#include "firmware_app/tune.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

#include "core/trajectory_eval.h"
#include "firmware_app/config.h"
#include "firmware_app/report.h"

namespace rdslam {

namespace {

// The numeric keys of the configuration with their allowed ranges ("section.key").
struct KeyInfo {
  bool integer = false;
  double lo = 0.0, hi = 0.0;
};

class KeyCollector : public ParamVisitor {
 public:
  KeyCollector(std::string prefix, std::map<std::string, KeyInfo>& numeric,
               std::set<std::string>& other)
      : prefix_(std::move(prefix)), numeric_(numeric), other_(other) {}
  void field(const char* key, int&, int lo, int hi, const char*) override {
    numeric_[name(key)] = {true, static_cast<double>(lo), static_cast<double>(hi)};
  }
  void field(const char* key, double&, double lo, double hi, const char*) override {
    numeric_[name(key)] = {false, lo, hi};
  }
  void field(const char* key, bool&, const char*) override { other_.insert(name(key)); }
  void field(const char* key, std::string&, const std::vector<std::string>&, const char*) override {
    other_.insert(name(key));
  }
  void field(const char* key, std::vector<int>&, int, int, const char*) override {
    other_.insert(name(key));
  }

 private:
  std::string name(const char* key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  std::string prefix_;
  std::map<std::string, KeyInfo>& numeric_;
  std::set<std::string>& other_;
};

[[noreturn]] void bad(const std::string& where, const std::string& what) {
  throw ConfigError("tune params " + where + ": " + what);
}

double number_of(const YAML::Node& n, const std::string& where, const std::string& field) {
  if (!n || !n.IsScalar()) bad(where, field + ": expected a number");
  const std::string raw = n.Scalar();
  char* end = nullptr;
  const double v = std::strtod(raw.c_str(), &end);
  if (raw.empty() || !end || *end != '\0' || !std::isfinite(v)) {
    bad(where, field + ": '" + raw + "' is not a number");
  }
  return v;
}

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

// Uniform double in [0, 1) from the top 53 bits: the same on every platform (the standard
// distributions are not specified bit for bit).
double unit(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

double clamp_round(const TuneParam& p, double v) {
  v = std::min(p.max, std::max(p.min, v));
  return p.integer ? std::round(v) : v;
}

std::string hex64(uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

std::optional<double> opt_number(const YAML::Node& n) {
  if (!n || !n.IsScalar()) return std::nullopt;
  char* end = nullptr;
  const std::string raw = n.Scalar();
  const double v = std::strtod(raw.c_str(), &end);
  if (raw.empty() || !end || *end != '\0' || !std::isfinite(v)) return std::nullopt;
  return v;
}

// Ranks with ties averaged (1-based).
std::vector<double> ranks(const std::vector<double>& v) {
  std::vector<size_t> idx(v.size());
  std::iota(idx.begin(), idx.end(), size_t{0});
  std::stable_sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return v[a] < v[b]; });
  std::vector<double> r(v.size());
  for (size_t i = 0; i < idx.size();) {
    size_t j = i;
    while (j + 1 < idx.size() && v[idx[j + 1]] == v[idx[i]]) ++j;
    const double avg = 0.5 * static_cast<double>(i + j) + 1.0;
    for (size_t k = i; k <= j; ++k) r[idx[k]] = avg;
    i = j + 1;
  }
  return r;
}

}  // namespace

std::vector<TuneParam> parse_tune_params(const std::string& yaml_text, const std::string& where) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    bad(where, "line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (!root.IsSequence() || root.size() == 0) {
    bad(where, "expected a non-empty list of {name, min, max, scale, type}");
  }
  AppConfig cfg;
  std::map<std::string, KeyInfo> numeric;
  std::set<std::string> other;
  for (auto& s : cfg.sections()) {
    KeyCollector kc(s.key, numeric, other);
    s.visit(kc);
  }
  std::vector<TuneParam> out;
  std::set<std::string> seen;
  for (size_t i = 0; i < root.size(); ++i) {
    const YAML::Node e = root[i];
    const std::string at = "entry " + std::to_string(i + 1);
    if (!e.IsMap()) bad(where, at + ": expected a mapping {name, min, max, scale, type}");
    for (const auto& kv : e) {
      const std::string k = kv.first.IsScalar() ? kv.first.Scalar() : "?";
      if (k != "name" && k != "min" && k != "max" && k != "scale" && k != "type") {
        bad(where, at + ": unknown field '" + k + "'; allowed: name, min, max, scale, type");
      }
    }
    if (!e["name"] || !e["name"].IsScalar()) bad(where, at + ": name: missing");
    TuneParam p;
    p.name = e["name"].Scalar();
    const std::string k = p.name;
    const auto it = numeric.find(k);
    if (it == numeric.end()) {
      if (other.count(k)) bad(where, k + ": not a numeric configuration key");
      bad(where, k + ": unknown configuration key (rdslam config lists them)");
    }
    if (!seen.insert(k).second) bad(where, k + ": listed twice");
    p.min = number_of(e["min"], where, k + ": min");
    p.max = number_of(e["max"], where, k + ": max");
    const std::string scale = e["scale"] ? e["scale"].Scalar() : "linear";
    if (scale != "linear" && scale != "log") {
      bad(where, k + ": scale: '" + scale + "' is not linear or log");
    }
    p.log_scale = scale == "log";
    const std::string type =
        e["type"] ? e["type"].Scalar() : (it->second.integer ? "int" : "float");
    if (type != "float" && type != "int")
      bad(where, k + ": type: '" + type + "' is not float or int");
    p.integer = type == "int";
    if (it->second.integer && !p.integer) {
      bad(where, k + ": type: float, but the configuration key is an integer");
    }
    if (!(p.min < p.max)) bad(where, k + ": min " + fmt(p.min) + " >= max " + fmt(p.max));
    if (p.min < it->second.lo || p.max > it->second.hi) {
      bad(where, k + ": range [" + fmt(p.min) + ", " + fmt(p.max) +
                     "] is outside the key's allowed range [" + fmt(it->second.lo) + ", " +
                     fmt(it->second.hi) + "]");
    }
    if (p.log_scale && p.min <= 0.0) bad(where, k + ": log scale needs min > 0");
    if (p.integer && (p.min != std::floor(p.min) || p.max != std::floor(p.max))) {
      bad(where, k + ": type int needs integer min and max");
    }
    out.push_back(p);
  }
  return out;
}

std::vector<TuneParam> load_tune_params(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("tune params: cannot read '" + path + "'");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_tune_params(ss.str(), "'" + path + "'");
}

std::vector<double> tune_start_values(AppConfig& cfg, const std::vector<TuneParam>& params) {
  std::map<std::string, double> values;
  class Reader : public ParamVisitor {
   public:
    Reader(std::string prefix, std::map<std::string, double>& out)
        : prefix_(std::move(prefix)), out_(out) {}
    void field(const char* key, int& v, int, int, const char*) override { out_[name(key)] = v; }
    void field(const char* key, double& v, double, double, const char*) override {
      out_[name(key)] = v;
    }
    void field(const char*, bool&, const char*) override {}
    void field(const char*, std::string&, const std::vector<std::string>&, const char*) override {}
    void field(const char*, std::vector<int>&, int, int, const char*) override {}

   private:
    std::string name(const char* key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
    std::string prefix_;
    std::map<std::string, double>& out_;
  };
  for (auto& s : cfg.sections()) {
    Reader r(s.key, values);
    s.visit(r);
  }
  std::vector<double> out;
  for (const auto& p : params) out.push_back(values.count(p.name) ? values[p.name] : p.min);
  return out;
}

std::string format_tune_value(const TuneParam& p, double v) {
  char buf[64];
  if (p.integer) {
    std::snprintf(buf, sizeof(buf), "%lld", static_cast<long long>(std::llround(v)));
  } else {
    std::snprintf(buf, sizeof(buf), "%.6g", v);
  }
  return buf;
}

std::vector<TuneCandidate> sample_candidates(const std::vector<TuneParam>& params,
                                             const std::vector<double>& start, int n,
                                             uint64_t seed) {
  std::vector<TuneCandidate> out;
  std::mt19937_64 rng(seed);
  for (int id = 0; id < n; ++id) {
    TuneCandidate c;
    c.id = id;
    for (size_t i = 0; i < params.size(); ++i) {
      const TuneParam& p = params[i];
      if (id == 0) {
        c.values.push_back(clamp_round(p, i < start.size() ? start[i] : p.min));
        continue;
      }
      const double u = unit(rng);
      double v = p.log_scale ? std::exp(std::log(p.min) + u * (std::log(p.max) - std::log(p.min)))
                             : p.min + u * (p.max - p.min);
      c.values.push_back(clamp_round(p, v));
    }
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<std::string> candidate_overrides(const std::vector<TuneParam>& params,
                                             const TuneCandidate& c) {
  std::vector<std::string> out;
  for (size_t i = 0; i < params.size() && i < c.values.size(); ++i) {
    out.push_back(params[i].name + "=" + format_tune_value(params[i], c.values[i]));
  }
  return out;
}

int HalvingPlan::evaluations() const {
  return std::accumulate(configs.begin(), configs.end(), 0);
}

HalvingPlan plan_halving(int budget, int rungs, int frames, int eta, int min_frames) {
  if (rungs < 1) throw std::invalid_argument("--rungs: must be >= 1");
  if (eta < 2) throw std::invalid_argument("eta: must be >= 2");
  if (rungs > 1 && frames <= 0) {
    throw std::invalid_argument("--rungs: halving over frame counts needs --frames N");
  }
  HalvingPlan plan;
  // The largest rung-0 size whose rungs fit in the budget.
  for (int n0 = budget; n0 >= 2; --n0) {
    std::vector<int> c;
    int n = n0;
    for (int r = 0; r < rungs; ++r) {
      c.push_back(n);
      n = std::max(1, n / eta);
    }
    if (std::accumulate(c.begin(), c.end(), 0) <= budget) {
      plan.configs = c;
      break;
    }
  }
  if (plan.configs.empty()) {
    throw std::invalid_argument("--budget: " + std::to_string(budget) + " holds no search of " +
                                std::to_string(rungs) + " rung(s) (at least 2 configurations)");
  }
  for (int r = 0; r < rungs; ++r) {
    int f = frames;
    for (int k = r; k < rungs - 1; ++k) f /= eta;
    plan.frames.push_back(frames <= 0 ? 0 : std::max(std::min(frames, min_frames), f));
  }
  return plan;
}

bool parse_tune_objective(const std::string& text, TuneObjective& out) {
  if (text == "ate") {
    out = TuneObjective::kAte;
  } else if (text == "consistency") {
    out = TuneObjective::kConsistency;
  } else {
    return false;
  }
  return true;
}

const char* to_string(TuneObjective o) {
  return o == TuneObjective::kAte ? "ate" : "consistency";
}

double sequence_score(TuneObjective o, const SeqResult& r) {
  if (!r.ok || !r.initialized) return kFailureScore;
  double e = 0.0;
  if (o == TuneObjective::kAte) {
    if (!r.ate_pct) return kFailureScore;
    e = *r.ate_pct;
  } else {
    if (!r.consistency_pct || !r.roughness_pct) return kFailureScore;
    e = *r.consistency_pct + *r.roughness_pct + r.disagreement_pct.value_or(0.0);
  }
  const double shortfall = std::max(0.0, kMinTracked - r.tracked_ratio_after_init);
  return std::min(kFailureScore, e + kTrackedWeight * 100.0 * shortfall);
}

double mean_score(TuneObjective o, const std::vector<SeqResult>& rs) {
  if (rs.empty()) return kFailureScore;
  double sum = 0.0;
  for (const auto& r : rs) sum += sequence_score(o, r);
  return sum / static_cast<double>(rs.size());
}

std::optional<double> trajectory_roughness_pct(const std::vector<Eigen::Vector3d>& positions) {
  if (positions.size() < 3) return std::nullopt;
  double path = 0.0, sum_sq = 0.0;
  for (size_t i = 1; i < positions.size(); ++i) path += (positions[i] - positions[i - 1]).norm();
  for (size_t i = 1; i + 1 < positions.size(); ++i) {
    sum_sq += (positions[i + 1] - 2.0 * positions[i] + positions[i - 1]).squaredNorm();
  }
  if (!(path > 0.0)) return std::nullopt;
  return 100.0 * std::sqrt(sum_sq / static_cast<double>(positions.size() - 2)) / path;
}

std::string run_key(const std::string& base_identity, const std::string& sequence, int frames,
                    const std::vector<std::string>& overrides) {
  uint64_t h = 1469598103934665603ull;
  auto add = [&h](const std::string& s) {
    for (unsigned char ch : s) {
      h ^= ch;
      h *= 1099511628211ull;
    }
    h ^= 0xff;  // separator
    h *= 1099511628211ull;
  };
  add(base_identity);
  add(sequence);
  add(std::to_string(frames));
  for (const auto& o : overrides) add(o);
  return hex64(h);
}

std::optional<double> trajectory_distance_pct(const Trajectory& a, const Trajectory& b) {
  if (a.size() < 3 || b.size() < 3) return std::nullopt;
  const EvalResult ab = evaluate_trajectories(a, b, EvalParams{});
  const EvalResult ba = evaluate_trajectories(b, a, EvalParams{});
  if (!ab.ok || !ba.ok || !(ab.gt_path_length_m > 0.0) || !(ba.gt_path_length_m > 0.0)) {
    return std::nullopt;
  }
  const double d = 0.5 * (ab.ate_pct_path.rmse + ba.ate_pct_path.rmse);
  if (!std::isfinite(d)) return std::nullopt;  // a non-finite pose in a trajectory file
  return d;
}

std::vector<std::optional<double>> tune_disagreement_pct(const std::vector<const Trajectory*>& runs,
                                                         const std::vector<bool>& peer) {
  if (peer.size() != runs.size()) {
    throw std::invalid_argument("tune_disagreement_pct: runs and peer differ in size");
  }
  const size_t n = runs.size();
  auto has = [&](size_t i) { return runs[i] != nullptr && runs[i]->size() >= 3; };
  // Pairwise distances once (symmetric); only pairs with a peer are needed.
  std::vector<std::optional<double>> d(n * n);
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      if (has(i) && has(j) && (peer[i] || peer[j])) {
        d[i * n + j] = d[j * n + i] = trajectory_distance_pct(*runs[i], *runs[j]);
      }
    }
  }
  std::vector<std::optional<double>> out(n);
  for (size_t i = 0; i < n; ++i) {
    if (!has(i)) continue;
    std::vector<double> v;
    for (size_t j = 0; j < n; ++j) {
      if (j != i && peer[j] && d[i * n + j]) v.push_back(*d[i * n + j]);
    }
    if (v.empty()) {
      out[i] = 0.0;
      continue;
    }
    std::sort(v.begin(), v.end());
    const size_t m = v.size();
    out[i] = m % 2 == 1 ? v[m / 2] : 0.5 * (v[m / 2 - 1] + v[m / 2]);
  }
  return out;
}

ResultStore::ResultStore(std::string path) : path_(std::move(path)) {
  std::ifstream in(path_);
  for (std::string line; std::getline(in, line);) {
    need_newline_ = in.eof();  // the last line had no newline
    if (line.empty()) continue;
    YAML::Node n;
    try {
      n = YAML::Load(line);  // JSON is YAML
    } catch (const YAML::Exception&) {
      continue;  // a line cut short by a kill
    }
    if (!n.IsMap() || !n["key"] || !n["ok"]) continue;
    SeqResult r;
    r.ok = n["ok"].Scalar() == "true";
    r.error = n["error"] && n["error"].IsScalar() ? n["error"].Scalar() : "";
    r.initialized = n["initialized"] && n["initialized"].Scalar() == "true";
    r.tracked_ratio = opt_number(n["tracked_ratio"]).value_or(0.0);
    r.tracked_ratio_after_init = opt_number(n["tracked_ratio_after_init"]).value_or(0.0);
    r.ate_pct = opt_number(n["ate_pct"]);
    r.ate_final_pct = opt_number(n["ate_final_pct"]);
    r.consistency_pct = opt_number(n["consistency_pct"]);
    r.roughness_pct = opt_number(n["roughness_pct"]);
    r.wall_s = opt_number(n["wall_s"]).value_or(0.0);
    index_[n["key"].Scalar()] = r;
    ++loaded_;
  }
}

const SeqResult* ResultStore::find(const std::string& key) const {
  const auto it = index_.find(key);
  return it == index_.end() ? nullptr : &it->second;
}

void ResultStore::append(const std::string& key, const std::string& sequence, int frames,
                         const std::vector<std::string>& overrides, const SeqResult& r) {
  // One line: a JsonWriter document with its newlines and indentation removed (strings never
  // hold a raw newline: the writer escapes them).
  JsonWriter w;
  w.begin_object();
  w.value("key", key);
  w.value("sequence", sequence);
  w.value("frames", frames);
  w.value("overrides", [&] {
    std::string s;
    for (const auto& o : overrides) s += (s.empty() ? "" : " ") + o;
    return s;
  }());
  w.value("ok", r.ok);
  w.value("error", r.error);
  w.value("initialized", r.initialized);
  w.value("tracked_ratio", r.tracked_ratio);
  w.value("tracked_ratio_after_init", r.tracked_ratio_after_init);
  w.value("ate_pct", r.ate_pct);
  w.value("ate_final_pct", r.ate_final_pct);
  w.value("consistency_pct", r.consistency_pct);
  w.value("roughness_pct", r.roughness_pct);
  w.value("wall_s", r.wall_s);
  w.end_object();
  std::string doc = w.str();
  std::string line;
  bool in_string = false;
  for (size_t i = 0; i < doc.size(); ++i) {
    const char ch = doc[i];
    if (ch == '"' && (i == 0 || doc[i - 1] != '\\')) in_string = !in_string;
    if (!in_string && (ch == '\n' || ch == ' ')) continue;
    line += ch;
  }
  FILE* f = std::fopen(path_.c_str(), "a");
  if (!f) throw std::runtime_error("cannot write " + path_);
  line = (need_newline_ ? "\n" : "") + line + '\n';
  need_newline_ = false;
  const bool ok = std::fwrite(line.data(), 1, line.size(), f) == line.size();
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error("write error on " + path_);
  index_[key] = r;
}

namespace {

// Runs the requests not yet in the store, then returns all results in request order.
std::vector<SeqResult> evaluate(const std::vector<EvalRequest>& reqs, const Evaluator& eval,
                                ResultStore& store, TuneOutcome& out, const TuneProgress& progress,
                                const std::string& what) {
  std::vector<EvalRequest> todo;
  std::vector<std::string> seen;  // a batch may ask twice for the same run (holdout: best = start)
  for (const auto& r : reqs) {
    if (std::find(seen.begin(), seen.end(), r.key) != seen.end()) continue;
    seen.push_back(r.key);
    ++out.runs_total;
    if (store.find(r.key)) {
      ++out.runs_resumed;
    } else {
      todo.push_back(r);
    }
  }
  if (progress) progress(0, todo.size(), what);
  if (!todo.empty()) {
    size_t finished = 0;
    eval(todo, [&](size_t i, const SeqResult& r) {
      store.append(todo[i].key, todo[i].sequence, todo[i].frames, todo[i].overrides, r);
      ++finished;
      if (progress) progress(finished, todo.size(), what);
    });
  }
  std::vector<SeqResult> all;
  for (const auto& r : reqs) {
    const SeqResult* s = store.find(r.key);
    all.push_back(s ? *s : SeqResult{});
  }
  return all;
}

// The disagreement term of every run in `res` (request order: configuration-major, `nseq`
// sequences per configuration), compared per sequence among the distinct runs of the batch.
void set_disagreement(const TuneSetup& setup, const std::vector<EvalRequest>& reqs,
                      std::vector<SeqResult>& res, size_t nseq) {
  if (!setup.online_trajectory || nseq == 0) return;
  for (size_t s = 0; s < nseq; ++s) {
    std::vector<size_t> first;   // distinct runs of sequence s: index of the first request
    std::vector<size_t> run_of;  // per request of sequence s: its distinct run
    for (size_t i = s; i < reqs.size(); i += nseq) {
      size_t u = 0;
      while (u < first.size() && reqs[first[u]].key != reqs[i].key) ++u;
      if (u == first.size()) first.push_back(i);
      run_of.push_back(u);
    }
    std::vector<Trajectory> trajs(first.size());
    std::vector<const Trajectory*> runs(first.size(), nullptr);
    std::vector<bool> peer(first.size(), false);
    for (size_t u = 0; u < first.size(); ++u) {
      const SeqResult& r = res[first[u]];
      if (!r.ok || !r.initialized) continue;
      trajs[u] = setup.online_trajectory(reqs[first[u]].key);
      runs[u] = &trajs[u];
      peer[u] = r.tracked_ratio_after_init >= kMinTracked;
    }
    const std::vector<std::optional<double>> x = tune_disagreement_pct(runs, peer);
    for (size_t k = 0, i = s; i < reqs.size(); ++k, i += nseq)
      res[i].disagreement_pct = x[run_of[k]];
  }
}

}  // namespace

TuneOutcome run_tune(const TuneSetup& setup, const Evaluator& eval, ResultStore& store,
                     const TuneProgress& progress) {
  TuneOutcome out;
  const HalvingPlan& plan = setup.plan;
  if (plan.configs.empty()) throw std::invalid_argument("tune: empty plan");
  const std::vector<TuneCandidate> cands =
      sample_candidates(setup.params, setup.start, plan.configs[0], setup.seed);
  for (const auto& c : cands) {
    out.candidates.push_back({c, 0, kFailureScore, {}, kFailureScore, {}});
  }
  std::vector<int> alive(cands.size());
  std::iota(alive.begin(), alive.end(), 0);
  const size_t nseq = setup.sequences.size();
  for (size_t r = 0; r < plan.configs.size(); ++r) {
    std::vector<EvalRequest> reqs;
    for (int ci : alive) {
      const auto ov = candidate_overrides(setup.params, cands[ci]);
      for (const auto& s : setup.sequences) {
        reqs.push_back(
            {run_key(setup.base_identity, s, plan.frames[r], ov), s, plan.frames[r], ov, true});
      }
    }
    const std::string what =
        "rung " + std::to_string(r + 1) + "/" + std::to_string(plan.configs.size()) + ": " +
        std::to_string(alive.size()) + " configs x " + std::to_string(nseq) + " sequences" +
        (plan.frames[r] > 0 ? " x " + std::to_string(plan.frames[r]) + " frames" : "");
    std::vector<SeqResult> res = evaluate(reqs, eval, store, out, progress, what);
    set_disagreement(setup, reqs, res, nseq);
    for (size_t k = 0; k < alive.size(); ++k) {
      CandidateScore& cs = out.candidates[alive[k]];
      cs.rung = static_cast<int>(r);
      cs.results.assign(res.begin() + k * nseq, res.begin() + (k + 1) * nseq);
      cs.objective = mean_score(setup.objective, cs.results);
      if (r == 0) {
        cs.rung0_objective = cs.objective;
        cs.rung0_results = cs.results;
      }
    }
    std::stable_sort(alive.begin(), alive.end(), [&](int a, int b) {
      const double oa = out.candidates[a].objective, ob = out.candidates[b].objective;
      return oa != ob ? oa < ob : a < b;
    });
    if (r + 1 < plan.configs.size()) {
      alive.resize(std::min(alive.size(), static_cast<size_t>(plan.configs[r + 1])));
    }
  }
  out.best = alive.front();
  if (!setup.holdout.empty()) {
    const int frames = plan.frames.back();
    struct Row {
      const char* label;
      std::vector<std::string> ov;
      bool base;
    };
    const std::vector<Row> rows = {
        {"defaults", {}, false},
        {"start", candidate_overrides(setup.params, cands[0]), true},
        {"best", candidate_overrides(setup.params, cands[out.best]), true},
    };
    std::vector<EvalRequest> reqs;
    for (const auto& row : rows) {
      for (const auto& s : setup.holdout) {
        reqs.push_back(
            {run_key(row.base ? setup.base_identity : std::string("defaults"), s, frames, row.ov),
             s, frames, row.ov, row.base});
      }
    }
    std::vector<SeqResult> res =
        evaluate(reqs, eval, store, out, progress, "holdout: defaults, start, best");
    set_disagreement(setup, reqs, res, setup.holdout.size());
    for (size_t i = 0; i < rows.size(); ++i) {
      HoldoutRow h;
      h.label = rows[i].label;
      h.results.assign(res.begin() + i * setup.holdout.size(),
                       res.begin() + (i + 1) * setup.holdout.size());
      h.objective = mean_score(setup.objective, h.results);
      out.holdout.push_back(std::move(h));
    }
  }
  return out;
}

double spearman(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size() || a.size() < 2) return 0.0;
  const std::vector<double> ra = ranks(a), rb = ranks(b);
  const double n = static_cast<double>(a.size());
  const double ma = std::accumulate(ra.begin(), ra.end(), 0.0) / n;
  const double mb = std::accumulate(rb.begin(), rb.end(), 0.0) / n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < ra.size(); ++i) {
    sab += (ra[i] - ma) * (rb[i] - mb);
    saa += (ra[i] - ma) * (ra[i] - ma);
    sbb += (rb[i] - mb) * (rb[i] - mb);
  }
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

double kendall_tau(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size() || a.size() < 2) return 0.0;
  double concordant = 0, discordant = 0, ties_a = 0, ties_b = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    for (size_t j = i + 1; j < a.size(); ++j) {
      const double da = a[i] - a[j], db = b[i] - b[j];
      if (da == 0 && db == 0) continue;
      if (da == 0) {
        ++ties_a;
      } else if (db == 0) {
        ++ties_b;
      } else if ((da > 0) == (db > 0)) {
        ++concordant;
      } else {
        ++discordant;
      }
    }
  }
  const double n0 = concordant + discordant;
  const double denom = std::sqrt((n0 + ties_a) * (n0 + ties_b));
  return denom > 0 ? (concordant - discordant) / denom : 0.0;
}

}  // namespace rdslam
