// Saved maps end to end (issue 24), through the whole threaded pipeline (`rdslam replay`,
// lossless): a map built on one trajectory through the office room (synth:static_halfsphere)
// is saved, checked with `rdslam map info`, and loaded to localize a different trajectory
// through the same room (synth:static_xyz: another camera path, same walls, posters, desk and
// seed, so the same world frame).
//
// Acceptance: relocalized within 10 frames; ATE in the map's frame at most 1% of the path. The
// map's frame is the frame of the saved map, at its scale: the Sim(3) that aligns the mapping
// run's final trajectory (keyframes after every bundle adjustment, the gauge the map was saved
// in) with the ground truth is computed once and applied unchanged to the localization run;
// the localization trajectory is not aligned by itself. With --localize the map is frozen
// (keyframe count unchanged); without it the map keeps growing.
//
// Also: a truncated or bit-flipped map, and a map from another camera, stop the replay at
// start with exit code 1 and a message naming the problem; `rdslam run` saves periodically,
// on an LCM command and at shutdown, keeping the last versions, and obeys / rejects commands.
#include <gtest/gtest.h>
#include <lcm/lcm.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "../support/run_command.h"
#include "core/trajectory.h"
#include "core/trajectory_eval.h"
#include "drivers/source_factory.h"
#include "rdslam/command_t.hpp"
#include "tests/support/lcm_test_bus.h"

namespace rdslam {
namespace {

using testing::read_text;
using testing::run_command;
using testing::ScratchDir;
using testing::shell_quote;

const char* kMapScene = "synth:static_halfsphere";
const char* kLocalizeScene = "synth:static_xyz";

std::string bin() {
  return RDSLAM_BINARY;
}

Trajectory ground_truth(const std::string& uri) {
  SourceOptions so;
  so.speed = 0.0;
  auto src = open_source(uri, so);
  const auto gt = src->ground_truth();
  return gt ? *gt : Trajectory{};
}

// A number after "key": in a JSON report (first occurrence).
double json_number(const std::string& doc, const std::string& key) {
  const std::regex re("\"" + key + "\":\\s*(-?[0-9.eE+-]+)");
  std::smatch m;
  if (!std::regex_search(doc, m, re)) return NAN;
  return std::stod(m[1]);
}

// Replays `uri` with --save-map DIR/NAME (and the final trajectory beside it); the map's path.
std::string build_map(const ScratchDir& dir, const std::string& uri, const std::string& name) {
  const std::string map = (dir.path() / name).string();
  const auto r =
      run_command(bin() + " replay " + shell_quote(uri) + " --save-map " + shell_quote(map) +
                  " --final-trajectory " + shell_quote(map + ".final.tum"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("map saved"), std::string::npos) << r.output;
  return r.exit_code == 0 ? map : "";
}

// One test (one mapping run) for the frozen and the growing map: the mapping replay is the
// expensive part.
TEST(MapLocalize, LocalizesAnotherTrajectoryInTheSavedMapFrozenOrGrowing) {
  ScratchDir dir("map-localize");
  const std::string map = build_map(dir, kMapScene, "room.map");
  ASSERT_FALSE(map.empty());
  const auto info = run_command(bin() + " map info " + shell_quote(map));
  ASSERT_EQ(info.exit_code, 0) << info.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(info.output, m, std::regex("keyframes +([0-9]+)"))) << info.output;
  const int map_keyframes = std::stoi(m[1]);
  EXPECT_GE(map_keyframes, 5);
  EXPECT_NE(info.output.find("orb"), std::string::npos);

  const std::string b_traj = (dir.path() / "b.tum").string();
  const std::string b_json = (dir.path() / "b.json").string();
  const auto loc = run_command(bin() + " replay " + kLocalizeScene + " --map " + shell_quote(map) +
                               " --localize --trajectory " + shell_quote(b_traj) + " --report " +
                               shell_quote(b_json));
  ASSERT_EQ(loc.exit_code, 0) << loc.output;
  const std::string report = read_text(b_json);
  const double first_pose = json_number(report, "first_pose_frame");
  EXPECT_GE(first_pose, 0);
  EXPECT_LE(first_pose, 10) << "relocalized within 10 frames";
  EXPECT_GE(json_number(report, "tracked_ratio"), 0.9);
  // Frozen: the map did not grow.
  EXPECT_EQ(json_number(report, "keyframes"), map_keyframes);

  // ATE in the map's frame (see the header comment).
  const Trajectory gt_a = ground_truth(kMapScene), gt_b = ground_truth(kLocalizeScene);
  const Trajectory a_final = read_trajectory(map + ".final.tum", TrajectoryFormat::kTum);
  const Trajectory b = read_trajectory(b_traj, TrajectoryFormat::kTum);
  EvalParams ep;
  const EvalResult ea = evaluate_trajectories(gt_a, a_final, ep);
  ASSERT_TRUE(ea.ok) << ea.error;
  const IndexPairs pairs = associate_by_time(gt_b, b, ep.max_diff_ns);
  ASSERT_GE(pairs.size(), 250u);
  double sq = 0.0, path = 0.0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const Eigen::Vector3d p = ea.alignment.apply(b[pairs[k].second].p_world_cam);
    sq += (p - gt_b[pairs[k].first].p_world_cam).squaredNorm();
    if (k > 0) {
      path += (gt_b[pairs[k].first].p_world_cam - gt_b[pairs[k - 1].first].p_world_cam).norm();
    }
  }
  const double rmse = std::sqrt(sq / static_cast<double>(pairs.size()));
  const double pct = 100.0 * rmse / path;
  std::printf("map frame ATE: %.4f m over %.2f m of path (%.3f%%); scale %.4f; %zu poses\n", rmse,
              path, pct, ea.alignment.scale, pairs.size());
  EXPECT_LE(pct, 1.0);

  // Without --localize the map keeps growing (and is saved again). The first 100 frames are
  // enough for new keyframes (27 of 23 when measured).
  const std::string json = (dir.path() / "c.json").string();
  const std::string grown = (dir.path() / "grown.map").string();
  const auto r = run_command(
      bin() + " replay " + shell_quote(std::string(kLocalizeScene) + "?frames=100") + " --map " +
      shell_quote(map) + " --report " + shell_quote(json) + " --save-map " + shell_quote(grown));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string grown_report = read_text(json);
  EXPECT_LE(json_number(grown_report, "first_pose_frame"), 10);
  const size_t prior = grown_report.find("\"prior_map\"");
  ASSERT_NE(prior, std::string::npos);
  const double prior_keyframes = json_number(grown_report.substr(prior), "keyframes");
  EXPECT_EQ(prior_keyframes, map_keyframes);
  EXPECT_GT(json_number(grown_report, "keyframes"), prior_keyframes) << "the map grew";
  const auto grown_info = run_command(bin() + " map info " + shell_quote(grown));
  ASSERT_EQ(grown_info.exit_code, 0) << grown_info.output;
  ASSERT_TRUE(std::regex_search(grown_info.output, m, std::regex("keyframes +([0-9]+)")));
  EXPECT_GT(std::stoi(m[1]), map_keyframes);
}

TEST(MapLocalize, DamagedOrMismatchedMapsAreRefusedAtStart) {
  ScratchDir dir("map-damaged");
  // A short mapping run is enough for a valid map of this camera.
  const std::string map = build_map(dir, std::string(kMapScene) + "?frames=60", "short.map");
  ASSERT_FALSE(map.empty());
  std::vector<char> bytes;
  {
    std::ifstream in(map, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GT(bytes.size(), 1000u);
  const std::string cut = (dir.path() / "cut.map").string();
  std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<long>(bytes.size() / 2));
  const std::string flip = (dir.path() / "flip.map").string();
  std::vector<char> flipped = bytes;
  flipped[flipped.size() / 3] ^= 0x04;
  std::ofstream(flip, std::ios::binary).write(flipped.data(), static_cast<long>(flipped.size()));
  const std::string base = bin() + " replay " + kLocalizeScene + " --localize --map ";
  const auto a = run_command(base + shell_quote(cut));
  EXPECT_EQ(a.exit_code, 1) << a.output;
  EXPECT_NE(a.output.find("--map " + cut + ": truncated"), std::string::npos) << a.output;
  const auto b = run_command(base + shell_quote(flip));
  EXPECT_EQ(b.exit_code, 1) << b.output;
  EXPECT_NE(b.output.find("checksum mismatch"), std::string::npos) << b.output;
  const auto c = run_command(base + shell_quote(map) + " --set camera.fx=500");
  EXPECT_EQ(c.exit_code, 1) << c.output;
  EXPECT_NE(c.output.find("map made with camera.fx = 525, this run uses 500"), std::string::npos)
      << c.output;
  const auto info = run_command(bin() + " map info " + shell_quote(cut));
  EXPECT_EQ(info.exit_code, 1);
  EXPECT_NE(info.output.find("truncated"), std::string::npos) << info.output;
}

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(MapRun, SavesPeriodicallyOnCommandAndAtShutdownAndObeysCommands) {
  ScratchDir dir("map-run");
  const std::string map = (dir.path() / "run.map").string();
  // A bus and command channel of this process only (tests/support/lcm_test_bus.h).
  const std::string url = rdslam::testing::private_lcm_url();
  const std::string command_channel = rdslam::testing::private_channel("RDSLAM_COMMAND");
  // While the daemon replays 4 s of video in real time, once it listens: localize, save_map,
  // an unknown code and a malformed message, as another process would send them; a reset once
  // the tracker has initialized.
  auto send_commands = [&] {
    lcm_t* lcm = lcm_create(url.c_str());
    ASSERT_NE(lcm, nullptr);
    for (int8_t code : {command_t::LOCALIZE, command_t::SAVE_MAP, int8_t(42)}) {
      command_t c;
      c.utime = 0;
      c.command = code;
      std::vector<uint8_t> buf(static_cast<size_t>(c.getEncodedSize()));
      c.encode(buf.data(), 0, static_cast<int>(buf.size()));
      lcm_publish(lcm, command_channel.c_str(), buf.data(), static_cast<unsigned>(buf.size()));
    }
    lcm_publish(lcm, command_channel.c_str(), "junk", 4);
    lcm_destroy(lcm);
  };
  // Once the tracker has a map: reset (a reset while INITIALIZING has nothing to discard).
  auto send_reset = [&] {
    lcm_t* lcm = lcm_create(url.c_str());
    ASSERT_NE(lcm, nullptr);
    command_t c;
    c.utime = 0;
    c.command = command_t::RESET;
    std::vector<uint8_t> buf(static_cast<size_t>(c.getEncodedSize()));
    c.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm_publish(lcm, command_channel.c_str(), buf.data(), static_cast<unsigned>(buf.size()));
    lcm_destroy(lcm);
  };
  const std::string cmd =
      bin() + " run --set " + shell_quote(std::string("source=") + kMapScene + "?frames=120") +
      " --set pipeline.replay_speed=1 --set lcm.url=" + shell_quote(url) +
      " --set lcm.command_channel=" + shell_quote(command_channel) +
      " --set map.save_period_s=1.5 --set map.keep=3 --save-map " + shell_quote(map) + " 2>&1";
  testing::CommandResult r;
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  char line[4096];
  bool sent = false, initialized = false, reset_sent = false;
  while (std::fgets(line, sizeof(line), p)) {
    r.output += line;
    if (!sent &&
        std::strstr(line, ("run: commands (rdslam.command_t) on " + command_channel).c_str())) {
      send_commands();
      sent = true;
    }
    initialized = initialized || std::strstr(line, "tracker: initialized with") != nullptr;
    if (sent && initialized && !reset_sent) {
      send_reset();
      reset_sent = true;
    }
  }
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  EXPECT_TRUE(sent && reset_sent) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("command: localize"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("commands: 3 accepted, 1 rejected, 1 malformed"), std::string::npos)
      << r.output;
  // The tracker starts a new map at its next frame.
  EXPECT_NE(
      r.output.find("tracker: reset requested (map epoch 0): re-initializing a new map, epoch 1"),
      std::string::npos)
      << r.output;
  // Periodic (1.5 s, 3 s) and commanded saves by the mapper thread, then the shutdown save.
  EXPECT_GE(count(r.output, "mapper: map saved to " + map), 2) << r.output;
  EXPECT_NE(r.output.find("run: map saved to " + map), std::string::npos) << r.output;
  EXPECT_EQ(count(r.output, "map not saved"), 0) << r.output;
  for (const std::string& f : {map, map + ".1", map + ".2"}) {
    const auto info = run_command(bin() + " map info " + shell_quote(f));
    EXPECT_EQ(info.exit_code, 0) << f << ": " << info.output;
  }
  EXPECT_FALSE(std::filesystem::exists(map + ".3"));
}

}  // namespace
}  // namespace rdslam
