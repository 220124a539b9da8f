#include "core/slam.h"

#include <chrono>
#include <cstdio>
#include <ctime>

namespace rdslam {

namespace {

// Keyframes the place-recognition database may hold: the current map and the kept earlier
// ones (recovery), each within the keyframe cap; sizes the tracker's relocalization scratch.
int places_capacity(const MapperParams& m) {
  return m.max_keyframes * (1 + m.max_epochs);
}

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

class TrackerStageImpl : public TrackerStage {
 public:
  TrackerStageImpl(const SlamParams& p, const CameraModel& cam, std::shared_ptr<SlamLink> link)
      : tracker_(p.tracker, p.features, p.mapper.ba, p.parsac, cam, std::move(link),
                 p.mapper.max_points, places_capacity(p.mapper)) {}
  TrackResult track(const Frame& frame) override {
    TrackResult r = tracker_.track(frame);
    if (debug_) tracker_.emit_debug_frame(frame, r);
    return r;
  }
  void start_with_map() { tracker_.start_with_map(); }
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
  bool final_frame_pose(const TrackResult& r, Pose* T_world_cam) const override {
    return mapper_.final_frame_pose(r, T_world_cam);
  }
  bool save_map(const std::string& path, int keep, std::string* message) override {
    MapInfo info;
    double ms = 0.0;
    if (!mapper_.save(path, keep, message, &info, &ms)) return false;
    if (message) {
      char m[256];
      std::snprintf(m, sizeof(m), "%d keyframes, %d points, %.1f MiB in %.0f ms", info.keyframes,
                    info.points, info.file_bytes / 1048576.0, ms);
      *message = m;
    }
    return true;
  }
  std::string summary() const override {
    const MapperStats& s = mapper_.stats();
    char m[160];
    std::snprintf(m, sizeof(m), "%d keyframes mapped (%d rejected), local BA yielded %d times",
                  s.keyframes_accepted, s.keyframes_rejected, s.ba_yielded);
    return m;
  }
  Mapper& mapper() { return mapper_; }

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

SlamStages make_slam_stages(const SlamParams& params, const CameraModel& camera,
                            const SlamStart& start) {
  auto link = make_slam_link(params, kCandidateSlots);
  link->localize_only.store(start.localize_only);
  auto tracker = std::make_unique<TrackerStageImpl>(params, camera, link);
  auto mapper = std::make_unique<MapperStageImpl>(params, camera, link);
  mapper->mapper().set_save_target(start.save_path, start.save_keep);
  mapper->mapper().set_save_writer(start.save_writer);
  if (start.prior) {
    mapper->mapper().load(std::move(*start.prior));
    tracker->start_with_map();
  }
  SlamStages s;
  s.tracker = std::move(tracker);
  s.mapper = std::move(mapper);
  s.link = std::move(link);
  return s;
}

OfflineRun run_offline(FrameSource& source, const SlamParams& params, const CameraModel& camera,
                       int max_frames, const std::function<void(const OfflineFrame&)>& on_frame) {
  auto link = make_slam_link(params, kCandidateSlots);
  Tracker tracker(params.tracker, params.features, params.mapper.ba, params.parsac, camera, link,
                  params.mapper.max_points, places_capacity(params.mapper));
  Mapper mapper(params.mapper, params.features, camera, link);
  mapper.set_change_detection(params.dynamic);
  mapper.set_keep_trail(true);  // the final trajectory (an offline run is bounded)
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
  for (const auto& f : run.frames) {
    const TrackResult& r = f.result;
    if (r.state != TrackingState::kTracking && r.state != TrackingState::kRelocalized) continue;
    StampedPose sp;
    sp.stamp_ns = f.stamp_ns;
    sp.p_world_cam = r.p_world_cam;
    sp.q_world_cam = r.q_world_cam;
    Pose T_world_cam;
    if (mapper.final_frame_pose(r, &T_world_cam)) {
      sp.q_world_cam = Eigen::Quaterniond(T_world_cam.R).normalized();
      sp.p_world_cam = T_world_cam.t;
    }
    run.final_trajectory.push_back(sp);
  }
  return run;
}

}  // namespace rdslam
