// The `rdslam` subcommands. Each lives in its own firmware_app/cmd_*.cpp and is listed in
// the table in main.cpp; a subcommand appears there (and in --help) only once it works.
// Each returns the process exit code: 0 success, 1 runtime failure, 2 usage/config error.
#pragma once

namespace rdslam {

int cmd_config(int argc, char** argv);
int cmd_run(int argc, char** argv);
int cmd_sources(int argc, char** argv);
int cmd_synth(int argc, char** argv);
int cmd_eval(int argc, char** argv);
int cmd_record(int argc, char** argv);
int cmd_bench(int argc, char** argv);
int cmd_replay(int argc, char** argv);
int cmd_vocab(int argc, char** argv);
int cmd_view(int argc, char** argv);
int cmd_map(int argc, char** argv);
int cmd_tune(int argc, char** argv);

}  // namespace rdslam
