// Soak test (issue 25): `rdslam replay synth:SCENE --loop N --realtime` for a fixed time, its
// resident memory (VmRSS of /proc/PID/status) sampled every second, then three verdicts:
//  - the replay exits normally;
//  - RSS does not grow after warm-up: the median of the last `window` seconds is within
//    `max_growth_pct` of the median of the `window` seconds right after `warmup` seconds;
//  - the map stays under its caps (mapper.max_keyframes, mapper.max_points) on every frame
//    (--map-log).
// Writes OUT/rss.csv (t_s, rss_mib),
// OUT/rss.png (top: the tracked camera path; below: RSS over time), OUT/map.csv,
// OUT/report.json, OUT/soak.txt (the numbers and verdicts) and exits 0 only when all hold.
//
//   soak_rss RDSLAM OUT [--seconds S] [--warmup S] [--window S] [--max-growth-pct P]
//            [--scene NAME] [--max-keyframes K] [--max-points P]
//
// tests/soak/soak.sh runs it (CI: 180 s; docs/reliability.md: the 30-minute run).
// Test program: allocates freely, one thread.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/trajectory.h"
#include "firmware_app/plot.h"

namespace {

namespace fs = std::filesystem;

double rss_mib(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;  // kB
  }
  return -1.0;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int usage() {
  std::fprintf(stderr,
               "usage: soak_rss RDSLAM OUT [--seconds S] [--warmup S] [--window S] "
               "[--max-growth-pct P] [--scene NAME] [--max-keyframes K] [--max-points P]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) return usage();
  const std::string rdslam = argv[1];
  const fs::path out = argv[2];
  double seconds = 180, warmup = 60, window = 30, max_growth_pct = 2.0;
  std::string scene = "rearrange";
  int max_keyframes = 12, max_points = 2000;  // reached within the first loops: caps enforced
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--seconds")
      seconds = std::atof(v.c_str());
    else if (k == "--warmup")
      warmup = std::atof(v.c_str());
    else if (k == "--window")
      window = std::atof(v.c_str());
    else if (k == "--max-growth-pct")
      max_growth_pct = std::atof(v.c_str());
    else if (k == "--scene")
      scene = v;
    else if (k == "--max-keyframes")
      max_keyframes = std::atoi(v.c_str());
    else if (k == "--max-points")
      max_points = std::atoi(v.c_str());
    else
      return usage();
  }
  if (!(seconds >= warmup + 2 * window) || window < 5) {
    std::fprintf(stderr, "soak_rss: need seconds >= warmup + 2 window, window >= 5\n");
    return 2;
  }
  fs::create_directories(out);
  // The built-in scenes are 300 frames at 30 fps: 10 s per loop at --realtime pacing.
  const int loops = static_cast<int>(std::ceil(seconds / 10.0));
  const std::vector<std::string> args = {rdslam,
                                         "replay",
                                         "synth:" + scene,
                                         "--loop",
                                         std::to_string(loops),
                                         "--realtime",
                                         "--set",
                                         "mapper.max_keyframes=" + std::to_string(max_keyframes),
                                         "--set",
                                         "mapper.max_points=" + std::to_string(max_points),
                                         "--map-log",
                                         (out / "map.csv").string(),
                                         "--report",
                                         (out / "report.json").string(),
                                         "--trajectory",
                                         (out / "trajectory.tum").string()};
  std::string cmdline;
  for (const auto& a : args) cmdline += a + " ";
  std::printf("soak: %s(%.0f s)\n", cmdline.c_str(), seconds);
  std::fflush(stdout);

  const fs::path log = out / "replay.log";
  const pid_t pid = fork();
  if (pid < 0) return 1;
  if (pid == 0) {
    FILE* f = std::freopen(log.c_str(), "w", stdout);
    if (!f || dup2(fileno(stdout), 2) < 0) _exit(127);
    std::vector<char*> av;
    for (const auto& a : args) av.push_back(const_cast<char*>(a.c_str()));
    av.push_back(nullptr);
    execv(av[0], av.data());
    _exit(127);
  }
  std::vector<double> t_s, rss;
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  for (int k = 1;; ++k) {
    std::this_thread::sleep_until(t0 + std::chrono::seconds(k));
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (waitpid(pid, &status, WNOHANG) == pid) {
      break;
    }
    const double r = rss_mib(pid);
    if (r > 0) {
      t_s.push_back(t);
      rss.push_back(r);
    }
    if (t > seconds + 120) {  // hung: the verdict is a failure
      std::fprintf(stderr, "soak: replay still running %.0f s after its end: killed\n", t);
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      break;
    }
  }
  const bool ok_exit = WIFEXITED(status) && WEXITSTATUS(status) == 0;

  {
    std::ofstream csv(out / "rss.csv");
    csv << "t_s,rss_mib\n";
    for (size_t i = 0; i < t_s.size(); ++i) csv << t_s[i] << "," << rss[i] << "\n";
  }
  std::vector<double> early, late;
  const double end_t = t_s.empty() ? 0.0 : t_s.back();
  for (size_t i = 0; i < t_s.size(); ++i) {
    if (t_s[i] >= warmup && t_s[i] < warmup + window) early.push_back(rss[i]);
    if (t_s[i] > end_t - window && t_s[i] <= end_t) late.push_back(rss[i]);
  }
  const double m_early = median(early), m_late = median(late);
  const double growth_pct = 100.0 * (m_late - m_early) / m_early;
  const bool ok_growth = early.size() >= 5 && late.size() >= 5 && growth_pct < max_growth_pct;

  // Map caps on every frame of the map log.
  int kf_max = 0, pts_max = 0;
  long long frames = 0, tracked = 0;
  {
    std::ifstream in(out / "map.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::stringstream ss(line);
      std::string cell[6];
      for (auto& c : cell) std::getline(ss, c, ',');
      if (cell[4].empty()) continue;
      ++frames;
      tracked += cell[2] == "TRACKING" || cell[2] == "RELOCALIZED";
      kf_max = std::max(kf_max, std::atoi(cell[3].c_str()));
      pts_max = std::max(pts_max, std::atoi(cell[4].c_str()));
    }
  }
  const bool ok_caps = frames > 0 && kf_max <= max_keyframes && pts_max <= max_points;

  rdslam::TrajectoryPlot plot;
  char title[256];
  std::snprintf(title, sizeof(title),
                "soak: synth:%s --loop --realtime, %.0f s\nRSS median %.1f MiB at %.0f-%.0f s, "
                "%.1f MiB in the last %.0f s (%+.2f%%)",
                scene.c_str(), end_t, m_early, warmup, warmup + window, m_late, window, growth_pct);
  plot.title = title;
  try {
    const rdslam::Trajectory traj =
        rdslam::read_trajectory((out / "trajectory.tum").string(), rdslam::TrajectoryFormat::kTum);
    std::vector<Eigen::Vector3d> p;
    for (const auto& sp : traj) p.push_back(sp.p_world_cam);
    plot.tracks.push_back({"tracked camera path", cv::Scalar(0, 0, 255), p, 1});
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "soak: no trajectory: %s\n", e.what());
  }
  plot.curves.push_back({"VmRSS", cv::Scalar(200, 80, 0), t_s, rss});
  plot.curve_title = "resident memory";
  plot.curve_y_label = "RSS [MiB]";
  rdslam::write_trajectory_plot(plot, (out / "rss.png").string());

  char summary[1024];
  std::snprintf(summary, sizeof(summary),
                "soak: %.0f s, %zu RSS samples, replay exit %s\n"
                "soak: RSS median %.1f MiB at %.0f-%.0f s, %.1f MiB over the last %.0f s: "
                "%+.2f%% (limit %.1f%%) %s\n"
                "soak: map max %d keyframes (cap %d), %d points (cap %d) over %lld frames "
                "(%.1f%% tracked) %s\n",
                end_t, rss.size(), ok_exit ? "0" : "FAILED", m_early, warmup, warmup + window,
                m_late, window, growth_pct, max_growth_pct, ok_growth ? "ok" : "FAILED", kf_max,
                max_keyframes, pts_max, max_points, frames, frames ? 100.0 * tracked / frames : 0.0,
                ok_caps ? "ok" : "FAILED");
  std::fputs(summary, stdout);
  std::ofstream(out / "soak.txt") << summary;
  if (!ok_exit) std::fprintf(stderr, "soak: replay failed, log %s\n", log.c_str());
  return ok_exit && ok_growth && ok_caps ? 0 : 1;
}
