// Feature extraction in two modes (config `features.mode`):
//  - "orb" (fast default, for 25 fps on an ARM core): FAST corners on an image pyramid,
//    bucketed over an image grid so features cover the whole view, intensity-centroid
//    orientation and 256-bit steered BRIEF descriptors (rBRIEF, Rublee et al. 2011) from our
//    own fixed test pattern. Pyramid, blur and FAST are our own (core/image_ops.h): all
//    buffers are preallocated and extract() does not allocate after the first frame of a
//    given size. Per-cell threshold fallback (after ORB-SLAM's extractor): a grid cell with
//    fewer than `fallback_cell_corners` corners at `fast_threshold` is detected again at
//    `min_fast_threshold`, so dim or low-contrast regions still get corners while
//    well-textured cells keep the stricter threshold. The result equals a detection at
//    min_fast_threshold restricted to those cells (a FAST score does not depend on the
//    threshold; the re-detection covers the non-maximum suppression's neighbours). By default
//    (`fallback_last`) those corners only fill what the main threshold leaves of the budget.
//  - "sift" (the paper, Sec. 3): SIFT keypoints and 128-float descriptors (OpenCV SIFT), to be
//    matched with a FLANN KD-tree and the ratio test c < 0.6. Allocates per frame (paper mode).
//    With sift_first_octave = 0 (default) OpenCV's SIFT runs on the image downscaled 2x
//    (INTER_AREA): its built-in 2x upsampling then restores the full resolution, which is
//    SIFT with first octave 0; keypoints are scaled back to full-resolution pixels.
//
// Keypoint coordinates are stored twice: raw pixels (for image patches) and undistorted ideal
// pixels (for geometry). A fixed spatial grid over the undistorted coordinates supports the
// radius searches of projection-guided matching.
//
// Ownership: FeatureExtractor owns its pyramid buffers; Features is a caller-owned buffer.
// Threads: one extractor per thread (the tracker owns one).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/image_ops.h"
#include "core/matching.h"
#include "core/params.h"

namespace rdslam {

struct FeatureParams {
  std::string mode = "orb";  // orb (fast default) | sift (the paper)
  int max_features = 1200;   // per frame
  int levels = 4;            // ORB pyramid levels
  double scale_factor = 1.2;
  int fast_threshold = 12;  // FAST threshold; cells rank corners by score
  int grid_cell_px = 40;    // bucketing cell size (pixels of each pyramid level)
  // Per-cell fallback: a cell with fewer than fallback_cell_corners corners at fast_threshold
  // is re-detected at min_fast_threshold (<= fast_threshold; equal, or 0 corners: off).
  int min_fast_threshold = 7;
  int fallback_cell_corners = 1;
  // true: the fallback's corners only fill what the main threshold's corners leave of a
  // level's quota (a frame whose quota the main threshold fills is unchanged); false: they
  // are ranked cell by cell with them (ORB-SLAM's behaviour; docs/slam.md compares both).
  bool fallback_last = true;
  // First SIFT octave: 0 = DoG scale space starts at the image resolution (SiftGPU's default,
  // Wu 2007, the SIFT of RDSLAM's implementation); -1 = Lowe's 2x upsampled image (OpenCV's
  // fixed choice; 4x the pixels, about 4x slower, adds only the finest-scale keypoints).
  int sift_first_octave = 0;

  void visit(ParamVisitor& v);
  std::string validate() const;
  // Acceptance rules of every matcher (config section `matching`, core/matching.h).
  MatchingParams matching;

  bool is_sift() const { return mode == "sift"; }
  // The one place the feature mode is decided: binary (ORB, Hamming) or float (SIFT, L2).
  bool binary() const { return !is_sift(); }
  int descriptor_bytes() const { return is_sift() ? 128 * 4 : 32; }
};

// One frame's features. Buffers grow to capacity once and are reused.
struct Features {
  int count = 0;
  int width = 0, height = 0;
  std::vector<cv::KeyPoint> kps;  // raw pixels; octave = pyramid level
  std::vector<cv::Point2f> un;    // undistorted ideal pixels
  std::vector<float> scale;       // pixel-noise scale of the feature (scale_factor^level)
  std::vector<int> level;
  cv::Mat desc;  // max rows x (32 CV_8U | 128 CV_32F); the first `count` rows are valid
  bool binary = true;

  // Grid over undistorted coordinates (CSR layout). It covers [grid_x0, grid_x0 + grid_w) x
  // [grid_y0, grid_y0 + grid_h) (grid_w or grid_h <= 0: [0, width) x [0, height)); the extractor
  // and the map reader set the camera's ideal_extent(), so with a lens the features it shows
  // outside the ideal rectangle are found too.
  float cell_px = 32.f;
  float grid_x0 = 0.f, grid_y0 = 0.f, grid_w = 0.f, grid_h = 0.f;
  int grid_cols = 0, grid_rows = 0;
  std::vector<int> cell_start;  // grid_cols*grid_rows + 1
  std::vector<int> cell_items;

  void build_grid();
  // Sets the grid's rectangle to `ideal_extent` (a CameraModel::ideal_extent(), whole pixels
  // around it; without a lens that is the image rectangle, as the default).
  void set_grid_extent(const cv::Rect2d& ideal_extent);
  // Indices of features within `radius` pixels of (x, y) with level in [min_level, max_level];
  // writes at most `cap` indices into `out`, returns their number.
  int radius_search(float x, float y, float radius, int min_level, int max_level, int* out,
                    int cap) const;
  const uint8_t* desc_ptr(int i) const { return desc.ptr<uint8_t>(i); }
  void copy_from(const Features& o);  // reuses capacity
};

class FeatureExtractor {
 public:
  FeatureExtractor(const FeatureParams& params, const CameraModel& camera);
  // `gray` is CV_8UC1 of the camera's size. Never throws; bad input yields count = 0.
  void extract(const cv::Mat& gray, Features& out);
  const FeatureParams& params() const { return params_; }

 private:
  void extract_orb(const cv::Mat& gray, Features& out);
  void extract_sift(const cv::Mat& gray, Features& out);
  void undistort(Features& out) const;
  void prepare(Features& out, int w, int h) const;
  // Appends to fast_buf_ the corners of `img` with min_fast_threshold <= score <
  // fast_threshold in the cells that have fewer than fallback_cell_corners corners.
  void cell_fallback(const cv::Mat& img);

  FeatureParams params_;
  CameraModel camera_;
  std::vector<cv::Mat> pyramid_, blurred_;
  std::vector<float> level_scale_;
  std::vector<int> level_quota_;
  std::vector<BilinearResize> resize_;  // per level (its tables depend on the sizes)
  GaussianBlur7 blur_{2.0};
  FastDetector fast_;
  std::vector<FastCorner> fast_buf_;
  std::vector<FastCorner> cell_buf_;  // one cell's re-detection at min_fast_threshold
  std::vector<int> rank_buf_, cell_count_, rank_hist_;
  std::vector<int> umax_;
  std::vector<int> pattern_;               // 256 pairs: x0 y0 x1 y1
  std::vector<int> rot_xy_;                // pattern rotated to each orientation bin
  std::vector<std::vector<int>> rot_off_;  // per level: rot_xy_ as pixel offsets
  std::vector<int> rot_step_;              // image step rot_off_ was built for
  cv::Rect2d grid_extent_;  // camera_.ideal_extent(): the rectangle of every Features' grid
  cv::Mat undistort_map_;   // CV_32FC2 per raw pixel -> ideal pixel (empty: no distortion)
  cv::Ptr<cv::SIFT> sift_;
  std::vector<cv::KeyPoint> sift_kps_;
  cv::Mat sift_desc_;
  cv::Mat sift_half_;  // the 2x downscaled input for sift_first_octave = 0
};

}  // namespace rdslam
