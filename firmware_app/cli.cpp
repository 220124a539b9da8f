#include "firmware_app/cli.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/log.h"

namespace rdslam {

ArgParser::ArgParser(std::string usage, std::string description)
    : usage_(std::move(usage)), description_(std::move(description)) {}

void ArgParser::option(const std::string& name, std::string* value, const std::string& metavar,
                       const std::string& doc) {
  Opt o;
  o.name = name;
  o.metavar = metavar;
  o.doc = doc;
  o.s = value;
  opts_.push_back(o);
}

void ArgParser::option(const std::string& name, double* value, const std::string& metavar,
                       const std::string& doc) {
  Opt o;
  o.name = name;
  o.metavar = metavar;
  o.doc = doc;
  o.d = value;
  opts_.push_back(o);
}

void ArgParser::flag(const std::string& name, bool* value, const std::string& doc) {
  Opt o;
  o.name = name;
  o.doc = doc;
  o.b = value;
  opts_.push_back(o);
}

void ArgParser::repeated(const std::string& name, std::vector<std::string>* values,
                         const std::string& metavar, const std::string& doc) {
  Opt o;
  o.name = name;
  o.metavar = metavar;
  o.doc = doc;
  o.list = values;
  opts_.push_back(o);
}

void ArgParser::positional(const std::string& metavar, std::string* value, const std::string& doc,
                           bool optional) {
  pos_.push_back({metavar, doc, value, optional});
}

void ArgParser::config_options(std::string* config_path, std::vector<std::string>* overrides) {
  option("--config", config_path, "FILE", "YAML configuration (default: built-in defaults)");
  repeated("--set", overrides, "KEY=VALUE",
           "override a configuration key, e.g. --set camera.fx=525 (repeatable)");
}

bool ArgParser::parse(int argc, char** argv) {
  size_t next_pos = 0;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(help().c_str(), stdout);
      return false;
    }
    if (a.size() > 2 && a[0] == '-' && a[1] == '-') {
      std::string inline_value;
      bool has_inline = false;
      const size_t eq = a.find('=');
      if (eq != std::string::npos) {
        inline_value = a.substr(eq + 1);
        a = a.substr(0, eq);
        has_inline = true;
      }
      const Opt* found = nullptr;
      for (const auto& o : opts_) {
        if (o.name == a) found = &o;
      }
      if (!found) throw UsageError("unknown option '" + a + "' (see --help)");
      if (found->b) {
        if (has_inline) throw UsageError("option '" + a + "' takes no value");
        *found->b = true;
        continue;
      }
      std::string value;
      if (has_inline) {
        value = inline_value;
      } else {
        if (i + 1 >= argc) throw UsageError("option '" + a + "' needs a value " + found->metavar);
        value = argv[++i];
      }
      if (found->s) *found->s = value;
      if (found->list) found->list->push_back(value);
      if (found->d) {
        char* end = nullptr;
        errno = 0;
        const double v = std::strtod(value.c_str(), &end);
        if (value.empty() || errno != 0 || *end != '\0' || !std::isfinite(v)) {
          throw UsageError("option '" + a + "': '" + value + "' is not a number");
        }
        *found->d = v;
      }
      continue;
    }
    if (next_pos >= pos_.size()) throw UsageError("unexpected argument '" + a + "' (see --help)");
    *pos_[next_pos++].value = a;
  }
  for (size_t p = next_pos; p < pos_.size(); ++p) {
    if (!pos_[p].optional)
      throw UsageError("missing argument " + pos_[p].metavar + " (see --help)");
  }
  return true;
}

std::string ArgParser::help() const {
  std::string out = "usage: " + usage_ + "\n\n" + description_ + "\n";
  if (!pos_.empty()) {
    out += "\narguments:\n";
    for (const auto& p : pos_) {
      std::string left = "  " + p.metavar;
      if (left.size() < 26) left.resize(26, ' ');
      out += left + " " + p.doc + "\n";
    }
  }
  out += "\noptions:\n";
  for (const auto& o : opts_) {
    std::string left = "  " + o.name + (o.metavar.empty() ? "" : " " + o.metavar);
    if (left.size() < 26) left.resize(26, ' ');
    out += left + " " + o.doc + "\n";
  }
  out += "  --help                   show this help\n";
  return out;
}

SourceOptions make_source_options(const AppConfig& cfg, const std::vector<std::string>& overrides,
                                  double speed) {
  SourceOptions so;
  so.speed = speed;
  so.config_camera = cfg.camera;
  so.camera_overridden = overrides_camera(overrides);
  so.lcm_url = cfg.lcm.url;
  so.v4l2 = cfg.v4l2;
  so.libcamera = cfg.libcamera;
  return so;
}

AppConfig load_cli_config(const std::string& config_path,
                          const std::vector<std::string>& overrides) {
  AppConfig cfg = load_config(config_path, overrides);
  LogLevel level = LogLevel::kInfo;
  if (parse_log_level(cfg.general.log_level.c_str(), level)) set_log_level(level);
  return cfg;
}

int run_subcommand(const char* command, const char* heading, const Subcommand* subs, size_t n,
                   int argc, char** argv) {
  if (argc < 1 || std::strcmp(argv[0], "--help") == 0 || std::strcmp(argv[0], "-h") == 0) {
    std::printf("usage: rdslam %s WHAT [options]   (rdslam %s WHAT --help)\n\n%s:\n", command,
                command, heading);
    for (size_t i = 0; i < n; ++i) std::printf("  %-10s %s\n", subs[i].name, subs[i].summary);
    return argc < 1 ? 2 : 0;
  }
  for (size_t i = 0; i < n; ++i) {
    if (std::strcmp(argv[0], subs[i].name) == 0) return subs[i].run(argc - 1, argv + 1);
  }
  throw UsageError(std::string("unknown ") + command + " command '" + argv[0] + "' (see rdslam " +
                   command + " --help)");
}

}  // namespace rdslam
