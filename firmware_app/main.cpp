// rdslam: monocular visual SLAM for dynamic environments. Entry point and subcommand table.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace {

struct Command {
  const char* name;
  const char* summary;
  int (*run)(int argc, char** argv);
};

// Only subcommands that work are listed here (and therefore in --help).
const Command kCommands[] = {
    {"config", "validate a configuration and print the effective values", rdslam::cmd_config},
    {"run", "the daemon: track the configured source, publish poses over LCM", rdslam::cmd_run},
    {"sources", "list the cameras (V4L2, libcamera) rdslam can use", rdslam::cmd_sources},
    {"synth", "render a synthetic dynamic scene with exact ground truth", rdslam::cmd_synth},
    {"record", "record a frame source into a TUM folder that replays bit-identically",
     rdslam::cmd_record},
    {"eval", "ATE/RPE of a trajectory against ground truth (TUM, EuRoC, KITTI)", rdslam::cmd_eval},
    {"bench", "benchmarks behind docs/ figures (bench parsac: Tables 1, 2)", rdslam::cmd_bench},
    {"replay", "run the SLAM pipeline on a recorded or synthetic source, with ATE",
     rdslam::cmd_replay},
    {"vocab", "place-recognition vocabulary: train, info, recall", rdslam::cmd_vocab},
    {"view", "serve a live web view (image, 3D map, state) of rdslam's LCM output",
     rdslam::cmd_view},
    {"map", "saved maps: info (what a map file holds)", rdslam::cmd_map},
    {"tune", "search configuration thresholds over sequences (random search, halving)",
     rdslam::cmd_tune},
};

void print_help() {
  std::printf(
      "rdslam %s: monocular visual SLAM that keeps working while the world moves\n"
      "(RDSLAM, Tan et al., ISMAR 2013).\n\n"
      "usage: rdslam COMMAND [options]     (rdslam COMMAND --help for details)\n\n"
      "commands:\n",
      RDSLAM_VERSION);
  for (const auto& c : kCommands) std::printf("  %-10s %s\n", c.name, c.summary);
  std::printf("\noptions:\n  --help     show this help\n  --version  print the version\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    print_help();
    return argc < 2 ? 2 : 0;
  }
  if (std::strcmp(argv[1], "--version") == 0) {
    std::printf("rdslam %s\n", RDSLAM_VERSION);
    return 0;
  }
  for (const auto& c : kCommands) {
    if (std::strcmp(argv[1], c.name) != 0) continue;
    try {
      return c.run(argc - 2, argv + 2);
    } catch (const rdslam::UsageError& e) {
      std::fprintf(stderr, "rdslam %s: %s\n", c.name, e.what());
      return 2;
    } catch (const rdslam::ConfigError& e) {
      std::fprintf(stderr, "rdslam: %s\n", e.what());
      return 2;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "rdslam %s: error: %s\n", c.name, e.what());
      return 1;
    }
  }
  std::fprintf(stderr, "rdslam: unknown command '%s' (see rdslam --help)\n", argv[1]);
  return 2;
}
