// Command-line parsing shared by every `rdslam` subcommand: declared options, positional
// arguments, generated --help text, and the common --config/--set pair.
//
// Threads: main thread, start-up only. parse() throws UsageError with a message that names
// the offending argument.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "drivers/source_factory.h"
#include "firmware_app/config.h"

namespace rdslam {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ArgParser {
 public:
  ArgParser(std::string usage, std::string description);
  // --name VALUE (string).
  void option(const std::string& name, std::string* value, const std::string& metavar,
              const std::string& doc);
  // --name VALUE (number); validated as a number.
  void option(const std::string& name, double* value, const std::string& metavar,
              const std::string& doc);
  // --name (flag).
  void flag(const std::string& name, bool* value, const std::string& doc);
  // --name VALUE, repeatable; every value appended.
  void repeated(const std::string& name, std::vector<std::string>* values,
                const std::string& metavar, const std::string& doc);
  // Positional argument (required unless `optional`).
  void positional(const std::string& metavar, std::string* value, const std::string& doc,
                  bool optional = false);
  // Adds --config FILE and --set KEY=VALUE.
  void config_options(std::string* config_path, std::vector<std::string>* overrides);

  // Returns false when --help was given (help already printed to stdout).
  bool parse(int argc, char** argv);
  std::string help() const;

 private:
  struct Opt {
    std::string name, metavar, doc;
    std::string* s = nullptr;
    double* d = nullptr;
    bool* b = nullptr;
    std::vector<std::string>* list = nullptr;
  };
  struct Pos {
    std::string metavar, doc;
    std::string* value;
    bool optional;
  };
  std::string usage_, description_;
  std::vector<Opt> opts_;
  std::vector<Pos> pos_;
};

// A command with subcommands (`rdslam bench WHAT`, `rdslam vocab WHAT`): one row each.
struct Subcommand {
  const char* name;
  const char* summary;
  int (*run)(int argc, char** argv);
};

// Runs the subcommand named by argv[0] with the remaining arguments. No argument or
// --help/-h prints "usage: rdslam COMMAND WHAT [options]" and the table under `heading`
// (returns 2 without an argument, 0 for --help); an unknown name throws UsageError.
int run_subcommand(const char* command, const char* heading, const Subcommand* subs, size_t n,
                   int argc, char** argv);

// SourceOptions from the configuration: camera (and whether --set camera.* overrode it), LCM
// URL, live-camera sections, and replay pacing `speed` (0 = as fast as read).
SourceOptions make_source_options(const AppConfig& cfg, const std::vector<std::string>& overrides,
                                  double speed);

// Loads --config/--set into an AppConfig, applying the log level. Throws ConfigError.
AppConfig load_cli_config(const std::string& config_path,
                          const std::vector<std::string>& overrides);

}  // namespace rdslam
