// Endurance replay (issue 8: "a looped rearrange replay keeps map points and keyframes below
// their caps, with no growth trend"): `rdslam replay synth:rearrange --loop N --map-log F`
// through the whole threaded pipeline. At every loop restart the camera jumps back to its
// first pose and the rearranged desk back to its first state, so the tracker relocalizes and
// map updating sees the same changes again, every 10 s of video.
//  - default caps, 12 loops (2 minutes of video): tracking holds, and the map levels off:
//    the per-loop maximum of map points in the last three loops is within 10% of that of
//    loops 4-6, and the keyframe count stops growing (docs/slam.md has the 10-minute run of
//    tests/replay/loop_rearrange.sh and its plot);
//  - tight caps (mapper.max_keyframes=10, mapper.max_points=1500), 4 loops: the caps hold on
//    every frame while the map keeps changing, and tracking still holds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../support/run_command.h"

namespace {

using rdslam::testing::run_command;

struct MapRow {
  long long seq = 0;
  std::string state;
  int keyframes = 0, points = 0;
};

std::vector<MapRow> read_map_log(const std::string& path) {
  std::vector<MapRow> rows;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string cell[6];
    for (auto& c : cell) std::getline(ss, c, ',');
    MapRow r;
    r.seq = std::stoll(cell[0]);
    r.state = cell[2];
    r.keyframes = std::stoi(cell[3]);
    r.points = std::stoi(cell[4]);
    rows.push_back(r);
  }
  return rows;
}

struct Loops {
  std::vector<int> max_points, max_keyframes;
  int tracked = 0, frames = 0;
};

Loops per_loop(const std::vector<MapRow>& rows, int frames_per_loop, int loops) {
  Loops l;
  l.max_points.assign(loops, 0);
  l.max_keyframes.assign(loops, 0);
  for (const MapRow& r : rows) {
    const int k = std::min<int>(loops - 1, static_cast<int>(r.seq / frames_per_loop));
    l.max_points[k] = std::max(l.max_points[k], r.points);
    l.max_keyframes[k] = std::max(l.max_keyframes[k], r.keyframes);
    ++l.frames;
    l.tracked += r.state == "TRACKING" || r.state == "RELOCALIZED";
  }
  return l;
}

std::string scratch(const char* name) {
  return (std::filesystem::temp_directory_path() /
          (std::string("rdslam_loop_") + name + "_" + std::to_string(::getpid()) + ".csv"))
      .string();
}

TEST(LoopReplay, RearrangeMapLevelsOffOverTwelveLoops) {
  constexpr int kLoops = 12, kFrames = 300;
  const std::string log = scratch("default");
  const auto r = run_command(std::string(RDSLAM_BINARY) + " replay synth:rearrange --loop " +
                             std::to_string(kLoops) + " --map-log " + log);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::vector<MapRow> rows = read_map_log(log);
  std::remove(log.c_str());
  ASSERT_EQ(static_cast<int>(rows.size()), kLoops * kFrames) << "lossless replay: every frame";
  const Loops l = per_loop(rows, kFrames, kLoops);
  for (int k = 0; k < kLoops; ++k) {
    std::printf("[loop] %2d: max %d points, %d keyframes\n", k, l.max_points[k],
                l.max_keyframes[k]);
  }
  EXPECT_GE(l.tracked, 0.95 * l.frames) << "tracked " << l.tracked << " of " << l.frames;
  auto mean = [](const std::vector<int>& v, int a, int b) {
    double s = 0;
    for (int k = a; k < b; ++k) s += v[k];
    return s / (b - a);
  };
  const double mid = mean(l.max_points, 3, 6), last = mean(l.max_points, kLoops - 3, kLoops);
  EXPECT_LE(last, 1.10 * mid) << "map points still growing: loops 4-6 " << mid << ", last 3 "
                              << last;
  EXPECT_LE(mean(l.max_keyframes, kLoops - 3, kLoops), mean(l.max_keyframes, 3, 6) + 2.0);
}

TEST(LoopReplay, TightCapsHoldOnEveryFrame) {
  constexpr int kLoops = 4, kFrames = 300, kMaxKf = 10, kMaxPoints = 1500;
  const std::string log = scratch("caps");
  const auto r = run_command(std::string(RDSLAM_BINARY) + " replay synth:rearrange --loop " +
                             std::to_string(kLoops) + " --map-log " + log +
                             " --set mapper.max_keyframes=" + std::to_string(kMaxKf) +
                             " --set mapper.max_points=" + std::to_string(kMaxPoints));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::vector<MapRow> rows = read_map_log(log);
  std::remove(log.c_str());
  ASSERT_EQ(static_cast<int>(rows.size()), kLoops * kFrames);
  int max_kf = 0, max_points = 0;
  for (const MapRow& row : rows) {
    max_kf = std::max(max_kf, row.keyframes);
    max_points = std::max(max_points, row.points);
  }
  std::printf("[loop] tight caps: at most %d keyframes (cap %d), %d points (cap %d)\n", max_kf,
              kMaxKf, max_points, kMaxPoints);
  EXPECT_LE(max_kf, kMaxKf);
  EXPECT_LE(max_points, kMaxPoints);
  EXPECT_GE(max_points, kMaxPoints / 2) << "the caps should bind in this test";
  const Loops l = per_loop(rows, kFrames, kLoops);
  EXPECT_GE(l.tracked, 0.90 * l.frames) << "tracked " << l.tracked << " of " << l.frames;
}

TEST(LoopReplay, BadArguments) {
  const std::string bin = RDSLAM_BINARY;
  auto r = run_command(bin + " replay 'synth:static_xyz?frames=5' --loop 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--loop"), std::string::npos) << r.output;
  r = run_command(bin +
                  " replay 'synth:static_xyz?frames=5' --loop 2 --map-log /nonexistent/x.csv");
  EXPECT_EQ(r.exit_code, 2) << r.output;  // refused before the run starts
  EXPECT_NE(r.output.find("/nonexistent/x.csv"), std::string::npos) << r.output;
}

}  // namespace
