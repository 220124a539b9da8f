#include "core/slam.h"

#include <chrono>
#include <ctime>

namespace rdslam {

namespace {

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

class TrackerStageImpl : public TrackerStage {
 public:
  TrackerStageImpl(const SlamParams& p, const CameraModel& cam, std::shared_ptr<SlamLink> link)
      : tracker_(p.tracker, p.features, p.mapper.ba, p.parsac, cam, std::move(link),
                 p.mapper.max_points, p.mapper.max_keyframes) {}
  TrackResult track(const Frame& frame) override {
    TrackResult r = tracker_.track(frame);
    if (debug_) tracker_.emit_debug_frame(frame, r);
    return r;
  }
  bool set_debug_sink(DebugFrameSink* sink) override {
    tracker_.set_debug_sink(sink);
    debug_ = sink != nullptr;
    return true;
  }

 private:
  Tracker tracker_;
  bool debug_ = false;
};

class MapperStageImpl : public MapperStage {
 public:
  MapperStageImpl(const SlamParams& p, const CameraModel& cam, std::shared_ptr<SlamLink> link)
      : mapper_(p.mapper, p.features, cam, std::move(link)) {
    mapper_.set_change_detection(p.dynamic);
  }
  bool step(int timeout_ms) override { return mapper_.step(timeout_ms); }
  void set_keep_trail(bool on) override { mapper_.set_keep_trail(on); }
  bool final_keyframe_pose(uint32_t epoch, int id, Pose* T_cam_world) const override {
    return mapper_.final_keyframe_pose(epoch, id, T_cam_world);
  }

 private:
  Mapper mapper_;
};

// Two slots: one candidate being mapped, one waiting. A third would only queue stale frames.
constexpr uint32_t kCandidateSlots = 2;

}  // namespace

std::string SlamParams::validate() const {
  std::string e = features.validate();
  if (!e.empty()) return e;
  if (tracker.reloc_min_inliers < tracker.min_inliers) {
    return "tracker.reloc_min_inliers: must be >= tracker.min_inliers";
  }
  return {};
}

std::shared_ptr<SlamLink> make_slam_link(const SlamParams& params, uint32_t ring_capacity) {
  auto link = std::make_shared<SlamLink>(ring_capacity, params.dynamic.observe_every_n());
  if (params.features.binary()) {
    const std::string& path = params.tracker.reloc_vocabulary;
    link->vocabulary = std::make_shared<const Vocabulary>(
        Vocabulary::load(path.empty() ? default_vocabulary_path() : path));
  }
  return link;
}

SlamStages make_slam_stages(const SlamParams& params, const CameraModel& camera) {
  auto link = make_slam_link(params, kCandidateSlots);
  SlamStages s;
  s.tracker = std::make_unique<TrackerStageImpl>(params, camera, link);
  s.mapper = std::make_unique<MapperStageImpl>(params, camera, link);
  return s;
}

OfflineRun run_offline(FrameSource& source, const SlamParams& params, const CameraModel& camera,
                       int max_frames, const std::function<void(const OfflineFrame&)>& on_frame) {
  auto link = make_slam_link(params, kCandidateSlots);
  Tracker tracker(params.tracker, params.features, params.mapper.ba, params.parsac, camera, link,
                  params.mapper.max_points, params.mapper.max_keyframes);
  Mapper mapper(params.mapper, params.features, camera, link);
  mapper.set_change_detection(params.dynamic);
  OfflineRun run;
  Frame frame;
  using Clock = std::chrono::steady_clock;
  for (int n = 0; max_frames <= 0 || n < max_frames; ++n) {
    const SourceStatus st = source.read(frame, 1000);
    if (st == SourceStatus::kEndOfStream) break;
    if (st != SourceStatus::kOk) continue;
    OfflineFrame of;
    of.stamp_ns = frame.stamp_ns;
    of.seq = frame.seq;
    const auto t0 = Clock::now();
    const double c0 = thread_cpu_ms();
    of.result = tracker.track(frame);
    of.track_cpu_ms = thread_cpu_ms() - c0;
    const auto t1 = Clock::now();
    while (mapper.step(0)) {
    }
    const auto t2 = Clock::now();
    of.track_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
    of.mapper_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
    run.frames.push_back(of);
    if (on_frame) on_frame(run.frames.back());
  }
  run.mapper = mapper.stats();
  run.tracker = tracker.stats();
  run.final_keyframes = static_cast<int>(mapper.map().keyframes.size());
  run.final_points = static_cast<int>(mapper.map().points.size());
  return run;
}

}  // namespace rdslam
