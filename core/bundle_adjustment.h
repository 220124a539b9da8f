// Bundle adjustment with Ceres (Sec. 3: "a work thread for frequent bundle adjustment of the
// estimated 3D points and camera poses", as in PTAM). Reprojection residuals in pixels
// divided by the feature's noise scale, with a Huber loss; a local window of keyframes is
// optimised while the keyframes outside it that see the same points are held fixed.
//
// Ownership: operates on the caller's Map. Threads: mapper thread (and the tracker once at
// initialization, for the two-view bundle adjustment).
#pragma once

#include <functional>
#include <vector>

#include "core/geometry.h"
#include "core/map.h"
#include "core/params.h"

namespace rdslam {

struct BundleAdjustmentParams {
  int window = 10;          // local BA: keyframes in all (the new one + its best covisible)
  int max_fixed = 20;       // fixed keyframes (outside the window) kept as anchors
  int iterations = 10;      // Levenberg-Marquardt iterations per pass
  double huber_px = 2.447;  // sqrt(5.991): Huber threshold on the normalised residual
  bool second_pass = true;  // re-run without the outliers found by the first pass
  bool keep_scale = true;   // gauge: with one fixed keyframe, undo the solution's scale change

  void visit(ParamVisitor& v);
};

struct BundleAdjustmentStats {
  int keyframes = 0, fixed = 0, points = 0, residuals = 0;
  int outliers_removed = 0;
  double initial_cost = 0, final_cost = 0;
  double rescale = 1.0;  // keep_scale: the scale applied to the solution
  bool stopped = false;  // `stop` ended it early (the second pass was skipped)
};

// Optimises the keyframes in `window_kfs` (those with Keyframe::fixed stay fixed) and all
// points they observe; other keyframes observing those points are fixed. Observations with a
// normalised squared error above 5.991 after optimisation are removed from the map, and
// points left with fewer than 2 observations are erased.
// With `keep_scale` and a single fixed keyframe (a young map: the window is the whole map) the
// reprojection cost is invariant to a scaling of everything else about that keyframe's centre,
// so the solution's scale is arbitrary; it is scaled back (stats.rescale) so that the optimised
// keyframes' centres keep, in least squares, the scale they had before (docs/slam.md, "The
// young map's scale gauge").
// `stop` (may be empty) is asked after every Levenberg-Marquardt iteration; when it returns true
// the solver ends there (ORB-SLAM's abort flag: the live mapper yields to a waiting keyframe),
// the second pass is skipped, and the result so far is kept: outliers removed and written back
// as after a full run (every accepted iteration lowers the cost).
BundleAdjustmentStats bundle_adjust(Map& map, const PinholeIntrinsics& K,
                                    const std::vector<int>& window_kfs,
                                    const BundleAdjustmentParams& params,
                                    const std::function<bool()>& stop = {});

}  // namespace rdslam
