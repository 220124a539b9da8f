#include <cstdio>

#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace rdslam {

int cmd_config(int argc, char** argv) {
  std::string config_path;
  std::vector<std::string> overrides;
  bool diff_only = false;
  ArgParser p("rdslam config [--config FILE] [--set KEY=VALUE ...] [--diff]",
              "Validate a configuration and print the effective values as YAML (what `run` and\n"
              "`replay` would use). Exits 2 with a message naming the key on any error.");
  p.config_options(&config_path, &overrides);
  p.flag("--diff", &diff_only, "print only the keys that differ from the built-in defaults");
  if (!p.parse(argc, argv)) return 0;
  AppConfig cfg = load_cli_config(config_path, overrides);
  if (diff_only) {
    for (const auto& kv : non_default_params(cfg)) std::printf("%s\n", kv.c_str());
  } else {
    std::fputs(dump_config(cfg).c_str(), stdout);
  }
  return 0;
}

}  // namespace rdslam
