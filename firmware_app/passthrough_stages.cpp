#include "firmware_app/passthrough_stages.h"

#include <algorithm>

#include "core/frame_source.h"

namespace rdslam {

PassthroughStages::PassthroughStages(std::optional<Trajectory> ground_truth,
                                     const PassthroughParams& params)
    : params_(params),
      gt_(ground_truth ? std::move(*ground_truth) : Trajectory{}),
      kf_ring_(64),
      tracker_(*this),
      mapper_(*this) {
  std::sort(gt_.begin(), gt_.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.stamp_ns < b.stamp_ns; });
  kf_store_.reserve(static_cast<size_t>(std::max(1, params_.max_keyframes)));
}

long PassthroughStages::nearest(int64_t stamp_ns) const {
  if (gt_.empty()) return -1;
  const auto it = std::lower_bound(gt_.begin(), gt_.end(), stamp_ns,
                                   [](const StampedPose& p, int64_t t) { return p.stamp_ns < t; });
  long best = -1;
  int64_t best_gap = 0;
  const long i = static_cast<long>(it - gt_.begin());
  for (long j : {i - 1, i}) {
    if (j < 0 || j >= static_cast<long>(gt_.size())) continue;
    const int64_t gap = std::llabs(gt_[j].stamp_ns - stamp_ns);
    if (best < 0 || gap < best_gap) {
      best = j;
      best_gap = gap;
    }
  }
  return best_gap <= params_.max_stamp_gap_ns ? best : -1;
}

TrackResult PassthroughStages::Tracker::track(const Frame& frame) {
  TrackResult r;
  r.covariance.fill(-1.0);
  const long i = owner_.nearest(frame.stamp_ns);
  if (i >= 0) {
    const StampedPose& p = owner_.gt_[i];
    r.state = TrackingState::kTracking;
    r.p_world_cam = p.p_world_cam;
    r.q_world_cam = p.q_world_cam;
    if (owner_.params_.keyframe_every > 0 && tracked_ % owner_.params_.keyframe_every == 0) {
      Keyframe* kf = owner_.kf_ring_.back();
      if (kf) {
        kf->seq = frame.seq;
        kf->pose = p;
        owner_.kf_ring_.commit();
        owner_.kf_bell_.ring();
      } else {
        owner_.kf_dropped_.fetch_add(1, std::memory_order_relaxed);
      }
    }
    ++tracked_;
  }
  r.keyframes = owner_.keyframes_.load(std::memory_order_acquire);
  return r;
}

bool PassthroughStages::Mapper::step(int timeout_ms) {
  PassthroughStages& o = owner_;
  Keyframe* kf = o.kf_ring_.front();
  if (!kf) {
    const uint32_t ticket = o.kf_bell_.ticket();
    kf = o.kf_ring_.front();
    if (!kf) {
      o.kf_bell_.wait(ticket, timeout_ms);
      kf = o.kf_ring_.front();
      if (!kf) return false;
    }
  }
  if (o.kf_store_.size() < o.kf_store_.capacity()) {
    o.kf_store_.push_back(*kf);  // within the reserved capacity: no allocation
    o.keyframes_.store(static_cast<int>(o.kf_store_.size()), std::memory_order_release);
  } else {
    o.kf_dropped_.fetch_add(1, std::memory_order_relaxed);
  }
  o.kf_ring_.pop();
  return true;
}

}  // namespace rdslam
