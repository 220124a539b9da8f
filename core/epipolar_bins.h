// Candidate lists for the mapper's epipolar search (new-point triangulation, Sec. 4 "track
// triangulation"): the features of one keyframe R bucketed by the epipolar lines that pass
// near them, so that each feature of the other keyframe is compared with a few dozen of R's
// features instead of all of them.
//
// Every epipolar line in R passes through R's epipole e (the projection of the other camera's
// centre), so a line is one angle phi around e. A feature at distance r from e and angle theta
// lies within `band` pixels of the line of angle phi iff r |sin(theta - phi)| <= band; it is
// put into every angle bin that overlaps [theta - asin(band / r), theta + asin(band / r)]
// (all bins when r <= band). candidates(l) returns the bin of l's angle: a superset of the
// features within their band of l, in the order they were given, so a best-of search over it
// (with the exact band test kept) finds exactly what a scan of all features finds, ties
// included. An epipole at infinity (pure sideways motion, e_z = 0) disables the bins:
// candidates() then returns every feature.
//
// Ownership: plain value type, reused across calls (its buffers grow to the largest feature set
// seen and are kept). Threads: the mapper thread.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace rdslam {

class EpipolarBins {
 public:
  // e: R's epipole in homogeneous pixel coordinates; idx[0..n): the features (any ids; kept in
  // this order); x[k], y[k]: the position of idx[k]; band[k]: its largest distance to an
  // accepted line, in pixels.
  void build(const Eigen::Vector3d& e, const int* idx, const double* x, const double* y,
             const double* band, int n);
  // The candidates for the line l (l.x() * u + l.y() * v + l.z() = 0, a line through e); *n gets
  // their number.
  const int* candidates(const Eigen::Vector3d& l, int* n) const;
  // Number of bins in use (0: disabled, every feature is a candidate).
  int bins() const { return bins_; }

 private:
  int bin_of(double phi) const;  // -1: no feature can be near a line of this angle

  std::vector<int> all_;               // every feature, in the given order
  std::vector<int> start_, items_;     // CSR: bin b's features are items_[start_[b], start_[b+1])
  std::vector<int> fill_;              // build scratch: next free slot per bin
  std::vector<double> theta_, alpha_;  // per feature: angle (folded), half-width
  std::vector<double> scratch_;        // build scratch: sorted angles
  int bins_ = 0;
  bool wrap_ = false;  // angles cover the whole half-turn: bins are cyclic over [-pi/2, pi/2)
  double lo_ = 0.0, width_ = 0.0;  // first bin's start angle, bin width
  Eigen::Vector2d e_ = Eigen::Vector2d::Zero();
};

}  // namespace rdslam
