#include "core/epipolar_bins.h"

#include <algorithm>
#include <cmath>

namespace rdslam {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMargin = 0.5;  // pixels added to every band: rounding of the line and epipole

// An angle folded into [0, pi): a line's direction and its opposite are the same line.
double fold(double a) {
  a = std::fmod(a, kPi);
  if (a < 0) a += kPi;
  return a >= kPi ? 0.0 : a;
}

}  // namespace

void EpipolarBins::build(const Eigen::Vector3d& e, const int* idx, const double* x, const double* y,
                         const double* band, int n) {
  all_.assign(idx, idx + n);
  bins_ = 0;
  if (n < 32 || !e.allFinite() || std::abs(e.z()) <= 1e-12 * e.norm()) return;
  e_ = e.head<2>() / e.z();
  theta_.resize(n);
  alpha_.resize(n);
  double alpha_max = 0.0;
  for (int k = 0; k < n; ++k) {
    const double dx = x[k] - e_.x(), dy = y[k] - e_.y();
    const double r = std::sqrt(dx * dx + dy * dy), b = band[k] + kMargin;
    theta_[k] = fold(std::atan2(dy, dx));
    alpha_[k] = r <= b ? kPi / 2 : std::asin(b / r);
    alpha_max = std::max(alpha_max, alpha_[k]);
  }
  // The features' angles cover an arc of the half-turn; the largest empty gap between two of
  // them (cyclically) is left out, so that the bins cover only the arc in use.
  std::vector<double>& sorted = scratch_;
  sorted.assign(theta_.begin(), theta_.end());
  std::sort(sorted.begin(), sorted.end());
  double gap = sorted.front() + kPi - sorted.back(), first = sorted.front();
  for (int k = 1; k < n; ++k) {
    if (sorted[k] - sorted[k - 1] > gap) {
      gap = sorted[k] - sorted[k - 1];
      first = sorted[k];
    }
  }
  double span = kPi - gap + 2 * alpha_max;
  wrap_ = span >= kPi;
  if (wrap_) {
    lo_ = 0.0;
    span = kPi;
  } else {
    lo_ = fold(first - alpha_max);
  }
  bins_ = std::clamp(n / 8, 16, 256);
  width_ = span / bins_;
  // Two passes over the features in their order (counts, then fill): every bin lists its
  // features in the given order.
  start_.assign(bins_ + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      for (int b = 0; b < bins_; ++b) start_[b + 1] += start_[b];
      items_.resize(start_[bins_]);
      fill_.assign(start_.begin(), start_.end() - 1);
    }
    for (int k = 0; k < n; ++k) {
      const double t = fold(theta_[k] - lo_);
      int b0 = static_cast<int>(std::floor((t - alpha_[k]) / width_));
      int b1 = static_cast<int>(std::floor((t + alpha_[k]) / width_));
      if (!wrap_) {
        b0 = std::clamp(b0, 0, bins_ - 1);
        b1 = std::clamp(b1, 0, bins_ - 1);
      } else if (b1 - b0 + 1 >= bins_) {
        b0 = 0;
        b1 = bins_ - 1;
      }
      for (int bb = b0; bb <= b1; ++bb) {
        const int b = ((bb % bins_) + bins_) % bins_;
        if (pass == 0) {
          ++start_[b + 1];
        } else {
          items_[fill_[b]++] = all_[k];
        }
      }
    }
  }
}

int EpipolarBins::bin_of(double phi) const {
  const double t = fold(phi - lo_);
  if (!wrap_ && t >= width_ * bins_) return -1;
  return std::min(static_cast<int>(t / width_), bins_ - 1);
}

const int* EpipolarBins::candidates(const Eigen::Vector3d& l, int* n) const {
  if (bins_ == 0 || !l.allFinite()) {
    *n = static_cast<int>(all_.size());
    return all_.data();
  }
  // The line's direction (-l.y, l.x) as an angle.
  const int b = bin_of(std::atan2(l.x(), -l.y()));
  if (b < 0) {
    *n = 0;
    return all_.data();
  }
  *n = start_[b + 1] - start_[b];
  return items_.data() + start_[b];
}

}  // namespace rdslam
