// `rdslam synth`: render a synthetic scenario to a TUM-format folder, a contact sheet, or a
// timing measurement (issue 5).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "drivers/synth_sequence.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace rdslam {

namespace {
// CPU time of this thread: on a loaded machine wall time measures the neighbours too.
double thread_cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
}  // namespace

int cmd_synth(int argc, char** argv) {
  std::string scenario, out_dir, sheet_path;
  double frames = -1, seed = -1;
  bool bench = false, list = false, print_yaml = false;
  ArgParser p(
      "rdslam synth SCENARIO|FILE.yaml [--out DIR] [--frames N] [--seed N]\n"
      "       [--contact-sheet OUT.png] [--bench] [--print-yaml] | --list",
      "Render a synthetic dynamic scene with exact ground truth (docs/synthetic.md).\n"
      "--out writes a TUM-format folder (rgb/, depth/, mask/, id/, rgb.txt, depth.txt,\n"
      "groundtruth.txt, camera.yaml, events.yaml) that `rdslam replay DIR` reads; DIR must\n"
      "not exist or be empty. The same scenes are the frame source synth:SCENARIO.");
  p.positional("SCENARIO", &scenario, "built-in scenario name (see --list) or a YAML file", true);
  p.option("--out", &out_dir, "DIR", "write the sequence as a TUM-format folder");
  p.option("--frames", &frames, "N", "number of frames (default: the scenario's, 300)");
  p.option("--seed", &seed, "N",
           "random seed (hand-held shake, noise, poster layout; the motion of a scenario with "
           "variants, e.g. dominant_object)");
  p.option("--contact-sheet", &sheet_path, "OUT.png",
           "write 8 frames with the dynamic mask overlaid in red");
  p.flag("--bench", &bench, "render every frame in memory and print frames per second");
  p.flag("--print-yaml", &print_yaml, "print the built-in scenario's YAML (a starting point)");
  p.flag("--list", &list, "list the built-in scenarios");
  if (!p.parse(argc, argv)) return 0;
  if (list) {
    for (const auto& n : synth_scenario_names()) std::printf("%s\n", n.c_str());
    return 0;
  }
  if (scenario.empty()) throw UsageError("a SCENARIO (or --list) is required");
  if (print_yaml) {
    const std::string y = synth_scenario_yaml(scenario);
    if (y.empty()) throw UsageError("'" + scenario + "' is not a built-in scenario");
    std::fputs(y.c_str(), stdout);
    return 0;
  }
  if (frames != -1 && (frames < 1 || frames != std::floor(frames)))
    throw UsageError("--frames must be a positive integer");
  if (seed != -1 && (seed < 0 || seed != std::floor(seed)))
    throw UsageError("--seed must be a non-negative integer");
  if (out_dir.empty() && sheet_path.empty() && !bench)
    throw UsageError("nothing to do: give --out DIR, --contact-sheet OUT.png or --bench");

  SynthSequence seq(scenario, static_cast<int>(frames), static_cast<int64_t>(seed));
  if (!sheet_path.empty()) {
    cv::Mat sheet = synth_contact_sheet(seq, 4, 2, 240);
    // 5 bits per channel: invisible at this size, and the PNG (sensor noise included) shrinks
    // to a size fit for the repository's docs/.
    sheet &= cv::Scalar(0xF8, 0xF8, 0xF8);
    if (!cv::imwrite(sheet_path, sheet, {cv::IMWRITE_PNG_COMPRESSION, 9})) {
      std::fprintf(stderr, "rdslam synth: cannot write %s\n", sheet_path.c_str());
      return 1;
    }
    std::printf("contact sheet: %s\n", sheet_path.c_str());
  }
  if (bench) {
    SynthFrame f;
    seq.render(0, f);  // warm-up: buffers allocated here
    std::vector<double> ms;
    ms.reserve(seq.frame_count());
    const auto t_all = std::chrono::steady_clock::now();
    const double cpu_all = thread_cpu_ms();
    for (int i = 0; i < seq.frame_count(); ++i) {
      const double c0 = thread_cpu_ms();
      seq.render(i, f);
      ms.push_back(thread_cpu_ms() - c0);
    }
    const double cpu_s = (thread_cpu_ms() - cpu_all) / 1e3;
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_all).count();
    std::sort(ms.begin(), ms.end());
    std::printf(
        "%s: %d frames %dx%d: %.1f frames/s of one core's CPU time (per frame median "
        "%.1f ms, p95 %.1f ms, max %.1f ms); wall clock %.1f frames/s\n",
        seq.scene().name.c_str(), seq.frame_count(), seq.camera().width, seq.camera().height,
        seq.frame_count() / cpu_s, ms[ms.size() / 2], ms[ms.size() * 95 / 100], ms.back(),
        seq.frame_count() / wall_s);
  }
  if (!out_dir.empty()) {
    int last_pct = -1;
    write_synth_dataset(seq, out_dir, [&](int done, int total) {
      const int pct = done * 100 / total;
      if (pct / 10 != last_pct / 10) {
        std::fprintf(stderr, "\rrdslam synth: %d/%d frames", done, total);
        last_pct = pct;
      }
    });
    std::fprintf(stderr, "\n");
    std::printf("wrote %d frames of %s to %s\n", seq.frame_count(), seq.scene().name.c_str(),
                out_dir.c_str());
  }
  return 0;
}

}  // namespace rdslam
