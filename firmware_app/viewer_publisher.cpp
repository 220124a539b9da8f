#include "firmware_app/viewer_publisher.h"

#include <lcm/lcm.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "bot_core/image_t.hpp"
#include "core/log.h"
#include "firmware_app/debug_video.h"
#include "firmware_app/pipeline.h"
#include "firmware_app/thread_setup.h"
#include "rdslam/map_t.hpp"

namespace rdslam {

namespace {

int64_t period_ns(double hz) {
  return hz > 0.0 ? static_cast<int64_t>(1e9 / hz) : 0;
}

// The features a record can hold without growing: features.max_features' upper bound plus
// the tracker's margin.
constexpr size_t kRecordFeatures = 10000 + 64;

void max_store(std::atomic<uint64_t>& a, uint64_t v) {
  uint64_t cur = a.load(std::memory_order_relaxed);
  while (v > cur && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

}  // namespace

ViewerPublisher::ViewerPublisher(const LcmParams& lcm, const ViewerParams& params,
                                 const CameraModel& camera)
    : lcm_params_(lcm), params_(params), camera_(camera), free_(kRecords), filled_(kRecords) {
  lcm_ = lcm_create(lcm_params_.url.c_str());
  if (!lcm_) throw std::runtime_error("lcm: cannot open provider URL '" + lcm_params_.url + "'");
  renderer_ = std::make_unique<DebugRenderer>(camera_, 30);
  for (int i = 0; i < kRecords; ++i) {
    records_[i] = std::make_unique<DebugFrame>();
    records_[i]->features.reserve(kRecordFeatures);
    free_.try_push(static_cast<uint8_t>(i));
  }
  record_period_ns_ = period_ns(std::max(params_.image_hz, params_.map_hz));
  thread_ = std::thread([this] { worker(); });
}

ViewerPublisher::~ViewerPublisher() {
  stop();
  if (lcm_) lcm_destroy(lcm_);
}

DebugFrame* ViewerPublisher::acquire_record(const Frame& /*frame*/) {
  if (record_period_ns_ <= 0) return nullptr;
  const int64_t now = mono_now_ns();
  if (now < next_record_ns_) return nullptr;
  uint8_t idx = 0;
  if (!free_.try_pop(idx)) {
    skipped_busy_.fetch_add(1, std::memory_order_relaxed);
    return nullptr;
  }
  // Due again one period after this frame (not after the previous due time: no burst after a
  // pause of the source).
  next_record_ns_ = now + record_period_ns_;
  lent_ns_[idx] = now;
  return records_[idx].get();
}

void ViewerPublisher::submit_record(DebugFrame* record) {
  for (int i = 0; i < kRecords; ++i) {
    if (records_[i].get() == record) {
      filled_.try_push(static_cast<uint8_t>(i));  // never full: kRecords slots, kRecords records
      records_n_.fetch_add(1, std::memory_order_relaxed);
      filled_bell_.ring();
      return;
    }
  }
}

void ViewerPublisher::on_debug_frame(DebugFrame&& /*frame*/) {}

void ViewerPublisher::stop() {
  if (!thread_.joinable()) return;
  stopping_.store(true, std::memory_order_release);
  filled_bell_.ring();
  thread_.join();
}

ViewerPublisherStats ViewerPublisher::stats() const {
  ViewerPublisherStats s;
  s.records = records_n_.load(std::memory_order_relaxed);
  s.skipped_busy = skipped_busy_.load(std::memory_order_relaxed);
  s.images = images_.load(std::memory_order_relaxed);
  s.maps = maps_.load(std::memory_order_relaxed);
  s.send_failures = failures_.load(std::memory_order_relaxed);
  s.last_image_bytes = last_image_bytes_.load(std::memory_order_relaxed);
  s.max_image_bytes = max_image_bytes_.load(std::memory_order_relaxed);
  s.max_map_bytes = max_map_bytes_.load(std::memory_order_relaxed);
  return s;
}

void ViewerPublisher::worker() {
  // A background thread: below the pipeline's threads under normal scheduling (SCHED_FIFO
  // pipeline threads preempt it anyway).
  set_this_thread_nice(10);
  for (;;) {
    const uint32_t ticket = filled_bell_.ticket();
    uint8_t idx = 0;
    if (filled_.try_pop(idx)) {
      DebugFrame& d = *records_[idx];
      process(d, lent_ns_[idx]);
      d.snapshot.reset();  // the mapper frees retired snapshots nobody holds
      free_.try_push(idx);
      continue;
    }
    if (stopping_.load(std::memory_order_acquire)) break;
    filled_bell_.wait(ticket, 200);
  }
}

bool ViewerPublisher::send(const char* channel, const std::vector<uint8_t>& buf) {
  if (lcm_publish(lcm_, channel, buf.data(), static_cast<unsigned>(buf.size())) != 0) {
    if (failures_.fetch_add(1, std::memory_order_relaxed) < 5) {
      RDSLAM_LOG_WARN("lcm: publishing on %s failed", channel);
    }
    return false;
  }
  return true;
}

void ViewerPublisher::process(DebugFrame& d, int64_t now) {
  // Half a record period of slack: records arrive at the fastest of the two rates.
  const int64_t slack = record_period_ns_ / 2;
  const bool image_due = params_.image_hz > 0.0 && now + slack >= next_image_ns_;
  const bool map_due = params_.map_hz > 0.0 && now + slack >= next_map_ns_;
  renderer_->observe(d);     // the invalidation ages (of the records it sees)
  renderer_->clear_track();  // not drawn (the top view is cropped away): bounded memory
  std::vector<uint8_t> buf;
  if (image_due) {
    next_image_ns_ = now + period_ns(params_.image_hz) - slack;
    cv::Mat canvas;
    renderer_->render(d, canvas);
    // Header and camera image (the top-view panel is the browser's 3D view's job).
    cv::Mat view =
        canvas(cv::Rect(0, 0, camera_.width, renderer_->image_origin().y + camera_.height));
    cv::Mat scaled;
    if (view.cols > params_.image_max_width) {
      const double s = static_cast<double>(params_.image_max_width) / view.cols;
      cv::resize(view, scaled,
                 cv::Size(params_.image_max_width, std::max(1, cvRound(view.rows * s))), 0, 0,
                 cv::INTER_AREA);
    } else {
      scaled = view;
    }
    bot_core::image_t m;
    m.utime = d.stamp_ns / 1000;
    m.width = scaled.cols;
    m.height = scaled.rows;
    m.row_stride = 0;  // compressed
    m.pixelformat = bot_core::image_t::PIXEL_FORMAT_MJPEG;
    cv::imencode(".jpg", scaled, m.data, {cv::IMWRITE_JPEG_QUALITY, params_.jpeg_quality});
    m.size = static_cast<int32_t>(m.data.size());
    m.nmetadata = 0;
    buf.resize(static_cast<size_t>(m.getEncodedSize()));
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    if (send(lcm_params_.image_channel.c_str(), buf)) {
      images_.fetch_add(1, std::memory_order_relaxed);
      last_image_bytes_.store(buf.size(), std::memory_order_relaxed);
      max_store(max_image_bytes_, buf.size());
    }
  }
  if (map_due) {
    next_map_ns_ = now + period_ns(params_.map_hz) - slack;
    rdslam::map_t m;
    m.utime = d.stamp_ns / 1000;
    m.seq = static_cast<int64_t>(d.seq);
    m.map_epoch = static_cast<int64_t>(d.result.epoch);
    m.total_points = 0;
    m.num_keyframes = 0;
    m.num_points = 0;
    if (d.snapshot) {
      const MapSnapshot& s = *d.snapshot;
      m.map_epoch = static_cast<int64_t>(s.epoch);
      m.total_points = s.rows();
      m.num_keyframes = static_cast<int32_t>(s.kf_pose.size());
      for (size_t k = 0; k < s.kf_pose.size(); ++k) {
        const Pose& T = s.kf_pose[k];  // T_cam_world
        const Eigen::Vector3d c = T.centre();
        const Eigen::Quaterniond q(T.R.transpose());
        m.keyframe_position.push_back({c.x(), c.y(), c.z()});
        m.keyframe_orientation.push_back({q.w(), q.x(), q.y(), q.z()});
        m.keyframe_id.push_back(k < s.kf_ids.size() ? s.kf_ids[k] : -1);
      }
      const int cap = params_.map_max_points;
      const int n_inv = std::min(static_cast<int>(s.invalid_p_world.size()), cap / 4);
      const int n_valid = std::min(s.rows(), cap - n_inv);
      auto add = [&m](const Eigen::Vector3d& p, int8_t valid) {
        m.point_position.push_back(
            {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
        m.point_valid.push_back(valid);
      };
      for (int i = 0; i < n_valid; ++i) {
        add(s.p_world[static_cast<size_t>(static_cast<int64_t>(i) * s.rows() / n_valid)], 1);
      }
      // The most recent invalidations (the list is oldest first).
      const size_t inv = s.invalid_p_world.size();
      for (size_t i = inv - static_cast<size_t>(n_inv); i < inv; ++i) add(s.invalid_p_world[i], 0);
      m.num_points = static_cast<int32_t>(m.point_valid.size());
    }
    buf.resize(static_cast<size_t>(m.getEncodedSize()));
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    if (send(lcm_params_.map_channel.c_str(), buf)) {
      maps_.fetch_add(1, std::memory_order_relaxed);
      max_store(max_map_bytes_, buf.size());
    }
  }
}

}  // namespace rdslam
