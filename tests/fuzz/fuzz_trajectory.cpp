// libFuzzer target: trajectory files as `rdslam eval` reads them (core/trajectory.h:
// TUM, EuRoC CSV, KITTI poses; format detection) and the evaluation of what was read
// (core/trajectory_eval.h: association, Sim3/SE3 alignment, ATE and RPE). Input: one byte
// choosing the format (0 TUM, 1 EuRoC, 2 KITTI, 3 detected), then the file. A malformed file
// must end in std::runtime_error naming file and line; evaluation reports bad trajectories in
// EvalResult::error. Anything else is a bug.
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "core/trajectory.h"
#include "core/trajectory_eval.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto path = rdslam::fuzz::scratch_dir() / "trajectory.txt";
  rdslam::fuzz::write_file(path, data + 1, size - 1);
  try {
    rdslam::TrajectoryFormat format = rdslam::TrajectoryFormat::kTum;
    switch (data[0] % 4) {
      case 1:
        format = rdslam::TrajectoryFormat::kEuroc;
        break;
      case 2:
        format = rdslam::TrajectoryFormat::kKitti;
        break;
      case 3:
        format = rdslam::detect_trajectory_format(path.string());
        break;
      default:
        break;
    }
    const rdslam::Trajectory traj = rdslam::read_trajectory(path.string(), format);
    if (traj.size() > 2000) return 0;  // the evaluation is O(n) per pose pair for RPE
    rdslam::EvalParams p;
    p.by_index = format == rdslam::TrajectoryFormat::kKitti;
    // Against itself and against itself without its first pose (a time shift).
    (void)rdslam::evaluate_trajectories(traj, traj, p);
    rdslam::Trajectory shifted(traj.begin() + (traj.empty() ? 0 : 1), traj.end());
    p.align = rdslam::Alignment::kSe3;
    (void)rdslam::evaluate_trajectories(traj, shifted, p);
  } catch (const std::runtime_error&) {
  }
  return 0;
}
