#include "firmware_app/config.h"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

namespace rdslam {

void LcmParams::visit(ParamVisitor& v) {
  v.field("url", url, {}, "LCM provider URL; ttl=0 keeps multicast on this host");
  v.field("pose_channel", pose_channel, {}, "channel of rdslam.pose_t, one per processed frame");
  v.field("status_channel", status_channel, {}, "channel of rdslam.status_t, 1 Hz");
  v.field("publish_bot_core_pose", publish_bot_core_pose,
          "also publish libbot2 bot_core.pose_t for existing tooling");
  v.field("bot_core_pose_channel", bot_core_pose_channel, {}, "channel of bot_core.pose_t");
  v.field("image_channel", image_channel, {}, "channel of the annotated bot_core.image_t (JPEG)");
  v.field("map_channel", map_channel, {}, "channel of rdslam.map_t (keyframes, map points)");
  v.field("command_channel", command_channel, {},
          "channel of rdslam.command_t that `rdslam run` obeys (empty: none; no authentication)");
}

void ViewerParams::visit(ParamVisitor& v) {
  v.field("image_hz", image_hz, 0.0, 30.0, "annotated JPEG images per second; 0 = none");
  v.field("map_hz", map_hz, 0.0, 10.0, "rdslam.map_t messages per second; 0 = none");
  v.field("map_max_points", map_max_points, 0, 100000, "map points per rdslam.map_t at most");
  v.field("image_max_width", image_max_width, 64, 4096, "wider images are downscaled");
  v.field("jpeg_quality", jpeg_quality, 10, 100, "JPEG quality of the image");
}

void GeneralParams::visit(ParamVisitor& v) {
  v.field("source", source, {}, "frame source URI (v4l2:, libcamera:, tum:, euroc:, ...)");
  v.field("log_level", log_level, {"debug", "info", "warn", "error"}, "stderr log level");
}

std::vector<AppConfig::Section> AppConfig::sections() {
  return {
      {"", [this](ParamVisitor& v) { general.visit(v); }},
      {"camera", [this](ParamVisitor& v) { camera.visit(v); }},
      {"lcm", [this](ParamVisitor& v) { lcm.visit(v); }},
      {"viewer", [this](ParamVisitor& v) { viewer.visit(v); }},
      {"v4l2", [this](ParamVisitor& v) { v4l2.visit(v); }},
      {"libcamera", [this](ParamVisitor& v) { libcamera.visit(v); }},
      {"pipeline", [this](ParamVisitor& v) { pipeline.visit(v); }},
      {"threads", [this](ParamVisitor& v) { threads.visit(v); }},
      {"features", [this](ParamVisitor& v) { slam.features.visit(v); }},
      {"matching", [this](ParamVisitor& v) { slam.features.matching.visit(v); }},
      {"tracker", [this](ParamVisitor& v) { slam.tracker.visit(v); }},
      {"mapper", [this](ParamVisitor& v) { slam.mapper.visit(v); }},
      {"parsac", [this](ParamVisitor& v) { parsac.visit(v); }},
      {"dynamic", [this](ParamVisitor& v) { slam.dynamic.visit(v); }},
      {"map", [this](ParamVisitor& v) { map.visit(v); }},
  };
}

void AppConfig::validate() const {
  const std::string cam = camera.validate();
  if (!cam.empty()) throw ConfigError("config: " + cam);
  if (general.source.empty()) throw ConfigError("config: source: must not be empty");
  if (lcm.url.empty()) throw ConfigError("config: lcm.url: must not be empty");
  if (const std::string e = v4l2.validate(); !e.empty()) throw ConfigError("config: " + e);
  if (const std::string e = slam.validate(); !e.empty()) throw ConfigError("config: " + e);
  if (const std::string e = parsac.validate(); !e.empty()) throw ConfigError("config: " + e);
  if (lcm.pose_channel.empty()) throw ConfigError("config: lcm.pose_channel: must not be empty");
  if (lcm.status_channel.empty()) {
    throw ConfigError("config: lcm.status_channel: must not be empty");
  }
  if (lcm.image_channel.empty()) throw ConfigError("config: lcm.image_channel: must not be empty");
  if (lcm.map_channel.empty()) throw ConfigError("config: lcm.map_channel: must not be empty");
}

namespace {

std::string fmt_num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (size_t i = 0; i < items.size(); ++i) out += (i ? ", " : "") + items[i];
  return out;
}

std::string dotted(const std::string& prefix, const char* key) {
  return prefix.empty() ? std::string(key) : prefix + "." + key;
}

[[noreturn]] void fail(const std::string& key, const std::string& what) {
  throw ConfigError("config: " + key + ": " + what);
}

bool parse_double(const std::string& s, double& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(s.c_str(), &end);
  return errno == 0 && end && *end == '\0' && std::isfinite(out);
}

bool parse_int(const std::string& s, int& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (errno != 0 || !end || *end != '\0' || v < -2147483647L || v > 2147483647L) return false;
  out = static_cast<int>(v);
  return true;
}

std::string scalar_of(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) fail(key, "expected a single value, not a list or mapping");
  return n.Scalar();
}

int to_int(const std::string& raw, const std::string& key, int lo, int hi) {
  int v = 0;
  if (!parse_int(raw, v)) fail(key, "value '" + raw + "' is not an integer");
  if (v < lo || v > hi) {
    fail(key, "value '" + raw + "' is out of range; allowed [" + std::to_string(lo) + ", " +
                  std::to_string(hi) + "]");
  }
  return v;
}

// Reads one YAML mapping into a parameter struct and records which keys it consumed.
class LoadVisitor : public ParamVisitor {
 public:
  LoadVisitor(const YAML::Node& node, std::string prefix)
      : node_(node), prefix_(std::move(prefix)) {}

  void field(const char* key, int& value, int lo, int hi, const char*) override {
    const YAML::Node n = take(key);
    if (!n) return;
    value = to_int(scalar_of(n, dotted(prefix_, key)), dotted(prefix_, key), lo, hi);
  }
  void field(const char* key, double& value, double lo, double hi, const char*) override {
    const YAML::Node n = take(key);
    if (!n) return;
    const std::string k = dotted(prefix_, key);
    const std::string raw = scalar_of(n, k);
    double v = 0;
    if (!parse_double(raw, v)) fail(k, "value '" + raw + "' is not a number");
    if (v < lo || v > hi) {
      fail(k, "value '" + raw + "' is out of range; allowed [" + fmt_num(lo) + ", " + fmt_num(hi) +
                  "]");
    }
    value = v;
  }
  void field(const char* key, bool& value, const char*) override {
    const YAML::Node n = take(key);
    if (!n) return;
    const std::string k = dotted(prefix_, key);
    const std::string raw = scalar_of(n, k);
    if (raw == "true" || raw == "True" || raw == "1" || raw == "yes" || raw == "on") {
      value = true;
    } else if (raw == "false" || raw == "False" || raw == "0" || raw == "no" || raw == "off") {
      value = false;
    } else {
      fail(k, "value '" + raw + "' is not a boolean; allowed true or false");
    }
  }
  void field(const char* key, std::string& value, const std::vector<std::string>& allowed,
             const char*) override {
    const YAML::Node n = take(key);
    if (!n) return;
    const std::string k = dotted(prefix_, key);
    const std::string raw = scalar_of(n, k);
    if (!allowed.empty()) {
      bool ok = false;
      for (const auto& a : allowed) ok = ok || a == raw;
      if (!ok) fail(k, "value '" + raw + "' is not allowed; allowed one of: " + join(allowed));
    }
    value = raw;
  }
  void field(const char* key, std::vector<int>& value, int lo, int hi, const char*) override {
    const YAML::Node n = take(key);
    if (!n) return;
    const std::string k = dotted(prefix_, key);
    std::vector<int> out;
    if (n.IsSequence()) {
      for (const auto& e : n) out.push_back(to_int(scalar_of(e, k), k, lo, hi));
    } else {
      out.push_back(to_int(scalar_of(n, k), k, lo, hi));
    }
    value = std::move(out);
  }

  const std::vector<std::string>& known() const { return known_; }

 private:
  // The value under `key`, or an undefined node when the key is absent or null.
  YAML::Node take(const char* key) {
    known_.emplace_back(key);
    const YAML::Node& map = node_;
    if (!map.IsMap()) return kAbsent();
    const YAML::Node n = map[key];
    if (!n.IsDefined() || n.IsNull()) return kAbsent();
    return n;
  }
  static YAML::Node kAbsent() {
    const YAML::Node empty(YAML::NodeType::Map);
    return empty["absent"];  // const lookup of a missing key: an undefined node
  }

  YAML::Node node_;
  std::string prefix_;
  std::vector<std::string> known_;
};

// Writes fields as "dotted.key" -> text.
class FlattenVisitor : public ParamVisitor {
 public:
  explicit FlattenVisitor(std::string prefix, std::vector<std::pair<std::string, std::string>>& out)
      : prefix_(std::move(prefix)), out_(out) {}
  void field(const char* key, int& value, int, int, const char*) override {
    put(key, std::to_string(value));
  }
  void field(const char* key, double& value, double, double, const char*) override {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.10g", value);
    put(key, buf);
  }
  void field(const char* key, bool& value, const char*) override {
    put(key, value ? "true" : "false");
  }
  void field(const char* key, std::string& value, const std::vector<std::string>&,
             const char*) override {
    put(key, value);
  }
  void field(const char* key, std::vector<int>& value, int, int, const char*) override {
    std::string s = "[";
    for (size_t i = 0; i < value.size(); ++i) s += (i ? ", " : "") + std::to_string(value[i]);
    put(key, s + "]");
  }

 private:
  void put(const char* key, std::string v) {
    out_.emplace_back(dotted(prefix_, key), std::move(v));
  }
  std::string prefix_;
  std::vector<std::pair<std::string, std::string>>& out_;
};

void apply_override(YAML::Node& root, const std::string& item) {
  const size_t eq = item.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ConfigError("config: --set '" + item + "': expected key=value");
  }
  const std::string key = item.substr(0, eq);
  const std::string raw = item.substr(eq + 1);
  std::vector<std::string> parts;
  std::stringstream ss(key);
  for (std::string p; std::getline(ss, p, '.');) {
    if (p.empty()) throw ConfigError("config: --set '" + item + "': empty key component");
    parts.push_back(p);
  }
  YAML::Node cur;
  cur.reset(root);
  for (size_t i = 0; i + 1 < parts.size(); ++i) {
    YAML::Node next = cur[parts[i]];
    if (!next.IsDefined() || next.IsNull()) {
      cur[parts[i]] = YAML::Node(YAML::NodeType::Map);
      next.reset(cur[parts[i]]);
    } else if (!next.IsMap()) {
      throw ConfigError("config: --set '" + item + "': " + parts[i] + " is not a section");
    }
    cur.reset(next);
  }
  if (!raw.empty() && raw.front() == '[') {
    try {
      cur[parts.back()] = YAML::Load(raw);
    } catch (const YAML::Exception& e) {
      throw ConfigError("config: --set '" + item + "': cannot parse list: " + e.msg);
    }
  } else {
    cur[parts.back()] = raw;
  }
}

}  // namespace

namespace {
// A mapping key as a plain name: YAML also allows sequences and mappings as keys
// ("? {fx: 1}: 2"), which as<std::string>() would throw as a yaml-cpp conversion error.
std::string key_name(const YAML::Node& key, const std::string& where) {
  if (!key.IsScalar()) {
    throw ConfigError("config: " + where + ": a key that is not a plain name (line " +
                      std::to_string(key.Mark().line + 1) + ")");
  }
  return key.Scalar();
}
}  // namespace

AppConfig load_config(const std::string& path, const std::vector<std::string>& overrides) {
  YAML::Node root(YAML::NodeType::Map);
  if (!path.empty()) {
    std::ifstream in(path);
    if (!in) throw ConfigError("config: cannot read '" + path + "'");
    try {
      root = YAML::Load(in);
    } catch (const YAML::Exception& e) {
      throw ConfigError("config: '" + path + "' line " + std::to_string(e.mark.line + 1) + ": " +
                        e.msg);
    }
    if (root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
    if (!root.IsMap()) throw ConfigError("config: '" + path + "': expected a mapping of keys");
  }
  for (const auto& o : overrides) apply_override(root, o);

  AppConfig cfg;
  std::set<std::string> top_known;
  for (auto& section : cfg.sections()) {
    if (section.key[0] == '\0') {
      LoadVisitor lv(root, "");
      section.visit(lv);
      top_known.insert(lv.known().begin(), lv.known().end());
      continue;
    }
    top_known.insert(section.key);
    const YAML::Node n = root[section.key];
    if (n.IsDefined() && !n.IsNull() && !n.IsMap()) {
      throw ConfigError(std::string("config: ") + section.key + ": expected a mapping of keys");
    }
    LoadVisitor lv(n.IsDefined() ? n : YAML::Node(YAML::NodeType::Map), section.key);
    section.visit(lv);
    if (n.IsDefined() && n.IsMap()) {
      for (const auto& kv : n) {
        const std::string k = key_name(kv.first, section.key);
        bool ok = false;
        for (const auto& kn : lv.known()) ok = ok || kn == k;
        if (!ok) {
          throw ConfigError("config: unknown key '" + std::string(section.key) + "." + k +
                            "'; allowed in " + section.key + ": " + join(lv.known()));
        }
      }
    }
  }
  for (const auto& kv : root) {
    const std::string k = key_name(kv.first, "top level");
    if (!top_known.count(k)) {
      throw ConfigError("config: unknown key '" + k + "'; allowed at top level: " +
                        join(std::vector<std::string>(top_known.begin(), top_known.end())));
    }
  }
  cfg.validate();
  return cfg;
}

namespace {
std::vector<std::pair<std::string, std::string>> flatten(AppConfig& cfg) {
  std::vector<std::pair<std::string, std::string>> out;
  for (auto& s : cfg.sections()) {
    FlattenVisitor fv(s.key, out);
    s.visit(fv);
  }
  return out;
}
}  // namespace

std::string dump_config(AppConfig& config) {
  std::string out;
  std::string current_section;
  for (auto& s : config.sections()) {
    std::vector<std::pair<std::string, std::string>> kv;
    FlattenVisitor fv("", kv);
    s.visit(fv);
    if (s.key[0] != '\0') out += std::string(s.key) + ":\n";
    for (const auto& [k, v] : kv) {
      const bool quote =
          v.empty() || v.find(':') != std::string::npos || v.find('#') != std::string::npos;
      out += (s.key[0] != '\0' ? "  " : "") + k + ": " + (quote ? "\"" + v + "\"" : v) + "\n";
    }
  }
  return out;
}

std::vector<std::string> non_default_params(AppConfig& config) {
  AppConfig defaults;
  const auto a = flatten(config);
  const auto b = flatten(defaults);
  std::vector<std::string> out;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
    if (a[i].second != b[i].second) out.push_back(a[i].first + "=" + a[i].second);
  }
  return out;
}

bool overrides_camera(const std::vector<std::string>& overrides) {
  for (const auto& o : overrides) {
    if (o.rfind("camera.", 0) == 0) return true;
  }
  return false;
}

}  // namespace rdslam
