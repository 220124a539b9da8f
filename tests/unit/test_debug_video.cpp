// Debug video/images (firmware_app/debug_video.h): the drawing puts the right colours at the
// projected points of a synthetic record, the writer produces the frames it was given, bad
// output paths are errors at construction, and the real tracker's debug record agrees with
// what track() returned.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "core/slam.h"
#include "drivers/source_factory.h"
#include "firmware_app/cli.h"
#include "firmware_app/debug_video.h"
#include "tests/support/run_command.h"

namespace rdslam {
namespace {

namespace fs = std::filesystem;

CameraModel test_camera() {
  CameraModel c;  // 640x480, f = 525, c = (319.5, 239.5), no distortion
  return c;
}

// A grey frame seen from the world origin (T_cam_world = identity) with one valid map point,
// one point behind the camera, one invalidated point and three classified features.
DebugFrame synthetic_frame(const std::shared_ptr<const MapSnapshot>& snap) {
  DebugFrame d;
  d.seq = 1;
  d.dataset_index = -1;
  d.result.state = TrackingState::kTracking;
  d.result.map_points = 2;
  d.result.keyframes = 1;
  d.has_pose = true;
  d.image = cv::Mat(480, 640, CV_8UC1, cv::Scalar(100));
  d.features.push_back({100.f, 100.f, DebugFeatureKind::kInlier});
  d.features.push_back({200.f, 300.f, DebugFeatureKind::kRejectedRobust});
  d.features.push_back({500.f, 120.f, DebugFeatureKind::kRejectedRefine});
  d.features.push_back({50.f, 400.f, DebugFeatureKind::kUnmatched});
  d.snapshot = snap;
  return d;
}

std::shared_ptr<MapSnapshot> synthetic_snapshot() {
  auto s = std::make_shared<MapSnapshot>();
  s->ids = {1, 2};
  s->p_world.push_back(Eigen::Vector3d(0.4, -0.2, 2.0));  // -> (424.5, 187.0)
  s->p_world.push_back(Eigen::Vector3d(0.4, 0.4, -2.0));  // behind: would be (214.5, 134.5)
  s->kf_ids = {0};
  s->kf_pose.push_back(Pose());
  s->invalid_ids = {7};
  s->invalid_p_world.push_back(Eigen::Vector3d(-0.6, 0.3, 1.5));  // -> (109.5, 344.5)
  return s;
}

cv::Vec3b bgr(const cv::Scalar& s) {
  return cv::Vec3b(uint8_t(s[0]), uint8_t(s[1]), uint8_t(s[2]));
}

// Pixel of the canvas at image coordinates (x, y).
cv::Vec3b at(const cv::Mat& canvas, const DebugRenderer& r, double x, double y) {
  const cv::Point o = r.image_origin();
  return canvas.at<cv::Vec3b>(o.y + cvRound(y), o.x + cvRound(x));
}

TEST(DebugRenderer, ColoursAtProjectedPointsAndFeatures) {
  const CameraModel cam = test_camera();
  DebugRenderer r(cam, /*recent_frames=*/5);
  const auto snap = synthetic_snapshot();
  const DebugFrame d = synthetic_frame(snap);
  r.observe(d);
  cv::Mat canvas;
  r.render(d, canvas);
  ASSERT_EQ(canvas.size(), r.canvas_size());
  ASSERT_EQ(canvas.type(), CV_8UC3);
  EXPECT_EQ(canvas.cols % 2, 0);
  EXPECT_EQ(canvas.rows % 2, 0);

  // Valid map point projected with the pose: cyan. u = 525 * 0.4 / 2 + 319.5 = 424.5.
  EXPECT_EQ(at(canvas, r, 424.5, 187.0), bgr(DebugColours::map_point()));
  // The point behind the camera is not drawn: background (100 dimmed).
  const cv::Vec3b bg = at(canvas, r, 600, 20);
  EXPECT_EQ(bg[0], bg[1]);
  EXPECT_LT(bg[0], 100);
  EXPECT_EQ(at(canvas, r, 214.5, 134.5), bg);
  // Recently invalidated point: red at u = 525 * -0.6 / 1.5 + 319.5 = 109.5, v = 344.5.
  EXPECT_EQ(at(canvas, r, 109.5, 344.5), bgr(DebugColours::invalidated()));
  EXPECT_EQ(r.recent_invalid(), 1);
  // Features at their raw pixels.
  EXPECT_EQ(at(canvas, r, 100, 100), bgr(DebugColours::inlier()));
  EXPECT_EQ(at(canvas, r, 200, 300), bgr(DebugColours::rejected_robust()));
  EXPECT_EQ(at(canvas, r, 500, 120), bgr(DebugColours::rejected_refine()));
  EXPECT_EQ(at(canvas, r, 50, 400), bg);  // unmatched features are not drawn
  // The cross is a cross: its arm end is coloured, the pixel beside the centre is not.
  EXPECT_EQ(at(canvas, r, 203, 303), bgr(DebugColours::rejected_robust()));
  EXPECT_NE(at(canvas, r, 204, 300), bgr(DebugColours::rejected_robust()));
}

int count_colour(const cv::Mat& img, const cv::Vec3b& c) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) n += img.at<cv::Vec3b>(y, x) == c;
  }
  return n;
}

TEST(DebugRenderer, TopViewShowsPointsKeyframesAndInvalidated) {
  const CameraModel cam = test_camera();
  DebugRenderer r(cam, 5);
  auto s = std::make_shared<MapSnapshot>();
  for (int i = 0; i < 100; ++i) {  // a wall 3 m ahead, 2 m wide
    s->ids.push_back(i);
    s->p_world.push_back(Eigen::Vector3d(-1.0 + 0.02 * i, 0.0, 3.0));
  }
  Pose kf1;
  kf1.t = Eigen::Vector3d(-0.5, 0, 0);  // centre (0.5, 0, 0)
  s->kf_ids = {0, 1};
  s->kf_pose = {Pose(), kf1};
  s->invalid_ids = {500};
  s->invalid_p_world.push_back(Eigen::Vector3d(0.0, 0.0, 1.5));
  DebugFrame d = synthetic_frame(s);
  d.T_cam_world = kf1;
  r.observe(d);
  cv::Mat canvas;
  r.render(d, canvas);
  // The plot area (without the legend rows at the bottom of the panel).
  const cv::Rect pr = r.panel_rect();
  const cv::Mat plot = canvas(cv::Rect(pr.x, pr.y + 20, pr.width, pr.height - 70));
  EXPECT_GT(count_colour(plot, cv::Vec3b(255, 255, 0)), 50);           // map points
  EXPECT_GT(count_colour(plot, bgr(DebugColours::keyframe())), 8);     // 2 squares
  EXPECT_GT(count_colour(plot, bgr(DebugColours::invalidated())), 4);  // the red dot
}

TEST(DebugRenderer, ProjectsThroughTheDistortionModel) {
  // Features are raw pixels, map points ideal 3D: the dot must land where the distorted
  // camera sees the point. Radial-tangential with k1 only: u = fx * x (1 + k1 r^2) + cx.
  CameraModel cam = test_camera();
  cam.k1 = -0.2;
  DebugRenderer r(cam, 5);
  auto s = std::make_shared<MapSnapshot>();
  s->ids = {1};
  s->p_world.push_back(Eigen::Vector3d(0.5, 0.25, 1.0));
  const DebugFrame d = synthetic_frame(s);
  r.observe(d);
  cv::Mat canvas;
  r.render(d, canvas);
  const double x = 0.5, y = 0.25, f = 1.0 + cam.k1 * (x * x + y * y);
  const double u = cam.fx * x * f + cam.cx, v = cam.fy * y * f + cam.cy;  // (528.5, 341.8)
  EXPECT_EQ(at(canvas, r, u, v), bgr(DebugColours::map_point()));
  EXPECT_NE(at(canvas, r, cam.fx * x + cam.cx, cam.fy * y + cam.cy),
            bgr(DebugColours::map_point()));
}

TEST(DebugRenderer, InvalidatedPointsFadeAfterRecentFrames) {
  const CameraModel cam = test_camera();
  DebugRenderer r(cam, /*recent_frames=*/3);
  const auto snap = synthetic_snapshot();
  const DebugFrame d = synthetic_frame(snap);
  cv::Mat canvas;
  for (int i = 0; i < 3; ++i) {
    r.observe(d);
    r.render(d, canvas);
    EXPECT_EQ(at(canvas, r, 109.5, 344.5), bgr(DebugColours::invalidated())) << "frame " << i;
  }
  r.observe(d);  // the 4th frame since the point was first listed
  r.render(d, canvas);
  EXPECT_NE(at(canvas, r, 109.5, 344.5), bgr(DebugColours::invalidated()));
  EXPECT_EQ(r.recent_invalid(), 0);
}

TEST(DebugRenderer, NoPoseNoProjection) {
  // INITIALIZING: nothing is projected, features are still drawn.
  const CameraModel cam = test_camera();
  DebugRenderer r(cam, 5);
  DebugFrame d = synthetic_frame(synthetic_snapshot());
  d.has_pose = false;
  d.result.state = TrackingState::kInitializing;
  r.observe(d);
  cv::Mat canvas;
  r.render(d, canvas);
  EXPECT_NE(at(canvas, r, 424.5, 187.0), bgr(DebugColours::map_point()));
  EXPECT_NE(at(canvas, r, 109.5, 344.5), bgr(DebugColours::invalidated()));
  EXPECT_EQ(at(canvas, r, 100, 100), bgr(DebugColours::inlier()));
}

TEST(DebugVideoWriter, WritesEveryNthFrameToVideoAndPngs) {
  testing::ScratchDir dir("debug-video");
  DebugVideoOptions o;
  o.video_path = (dir.path() / "out.mp4").string();
  o.images_dir = (dir.path() / "img").string();
  o.every = 2;
  const auto snap = synthetic_snapshot();
  DebugVideoWriter w(o, test_camera());
  for (int i = 0; i < 7; ++i) {
    DebugFrame d = synthetic_frame(snap);
    d.dataset_index = 10 + i;
    w.on_debug_frame(std::move(d));
  }
  const DebugVideoStats st = w.finish();
  EXPECT_EQ(st.received, 7);
  EXPECT_EQ(st.dropped, 0);
  EXPECT_EQ(st.drawn, 4);  // records 0, 2, 4, 6
  EXPECT_EQ(st.video_frames, 4);
  EXPECT_EQ(st.images, 4);
  EXPECT_TRUE(st.error.empty()) << st.error;
  for (int i : {10, 12, 14, 16}) {
    const fs::path png = dir.path() / "img" / cv::format("frame_%06d.png", i);
    ASSERT_TRUE(fs::exists(png)) << png;
    const cv::Mat im = cv::imread(png.string());
    DebugRenderer r(test_camera(), 5);
    EXPECT_EQ(im.size(), r.canvas_size());
    EXPECT_EQ(at(im, r, 100, 100), bgr(DebugColours::inlier()));  // PNG is lossless
  }
  EXPECT_FALSE(fs::exists(dir.path() / "img" / "frame_000011.png"));
  cv::VideoCapture cap(o.video_path, cv::CAP_FFMPEG);
  ASSERT_TRUE(cap.isOpened());
  int frames = 0;
  for (cv::Mat f; cap.read(f);) {
    ++frames;
    EXPECT_EQ(f.size(), DebugRenderer(test_camera(), 5).canvas_size());
  }
  EXPECT_EQ(frames, 4);
}

TEST(DebugVideoWriter, RealTimeModeDropsInsteadOfWaitingAndCountsIt) {
  // Not lossless: a full queue drops the record (the tracker never waits). Whatever the
  // timing, every record is either drawn or counted as dropped.
  testing::ScratchDir dir("debug-video-rt");
  DebugVideoOptions o;
  o.images_dir = (dir.path() / "img").string();
  o.lossless = false;
  o.queue_frames = 1;
  const auto snap = synthetic_snapshot();
  DebugVideoWriter w(o, test_camera());
  for (int i = 0; i < 20; ++i) {
    DebugFrame d = synthetic_frame(snap);
    d.dataset_index = i;
    w.on_debug_frame(std::move(d));
  }
  const DebugVideoStats st = w.finish();
  EXPECT_EQ(st.received, 20);
  EXPECT_EQ(st.drawn + st.dropped, 20);
  EXPECT_EQ(st.images, st.drawn);
  EXPECT_GE(st.drawn, 1);
}

std::string usage_error(const DebugVideoOptions& o) {
  try {
    DebugVideoWriter w(o, test_camera());
  } catch (const UsageError& e) {
    return e.what();
  }
  return "";
}

TEST(DebugVideoWriter, BadPathsAreUsageErrorsNamingThePath) {
  testing::ScratchDir dir("debug-video-bad");
  DebugVideoOptions o;
  o.video_path = (dir.path() / "no_such_dir" / "out.mp4").string();
  std::string e = usage_error(o);
  EXPECT_NE(e.find(o.video_path), std::string::npos) << e;

  o.video_path = dir.path().string();  // a directory
  e = usage_error(o);
  EXPECT_NE(e.find(o.video_path), std::string::npos) << e;

  o.video_path = (dir.path() / "out.unknown_container").string();  // no muxer for it
  e = usage_error(o);
  EXPECT_NE(e.find(o.video_path), std::string::npos) << e;

  o.video_path.clear();
  const fs::path file = dir.path() / "a_file";
  std::ofstream(file) << "x";
  o.images_dir = (file / "img").string();  // parent is a regular file
  e = usage_error(o);
  EXPECT_NE(e.find(o.images_dir), std::string::npos) << e;
}

// The real tracker on a rendered sequence: every frame yields one record, and it reports what
// track() decided (same state, as many inlier features as result.inliers, a pose and a
// snapshot once tracking).
class CollectingSink : public DebugFrameSink {
 public:
  void on_debug_frame(DebugFrame&& f) override { frames.push_back(std::move(f)); }
  std::vector<DebugFrame, Eigen::aligned_allocator<DebugFrame>> frames;
};

TEST(TrackerDebugRecord, AgreesWithTrackResult) {
  SlamParams params;
  params.tracker.sync_mapper = false;
  const CameraModel cam = test_camera();
  SlamStages stages = make_slam_stages(params, cam);
  CollectingSink sink;
  ASSERT_TRUE(stages.tracker->set_debug_sink(&sink));
  SourceOptions so;
  std::unique_ptr<FrameSource> src = open_source("synth:walking_xyz?frames=50", so);
  Frame frame;
  std::vector<TrackResult> results;
  while (src->read(frame, 1000) == SourceStatus::kOk) {
    results.push_back(stages.tracker->track(frame));
    while (stages.mapper->step(0)) {
    }
  }
  ASSERT_EQ(sink.frames.size(), results.size());
  int tracked = 0, with_rejections = 0;
  for (size_t i = 0; i < results.size(); ++i) {
    const DebugFrame& d = sink.frames[i];
    const TrackResult& r = results[i];
    EXPECT_EQ(d.result.state, r.state);
    EXPECT_EQ(d.image.size(), cv::Size(cam.width, cam.height));
    if (r.state != TrackingState::kTracking && r.state != TrackingState::kRelocalized) continue;
    ++tracked;
    EXPECT_TRUE(d.has_pose);
    EXPECT_EQ(count_features(d, DebugFeatureKind::kInlier), r.inliers) << "frame " << i;
    // The record's pose is the published one.
    EXPECT_LT((d.T_cam_world.centre() - r.p_world_cam).norm(), 1e-9);
    if (i > 0 && sink.frames[i - 1].result.state == TrackingState::kTracking) {
      EXPECT_TRUE(d.snapshot != nullptr);
    }
    with_rejections += count_features(d, DebugFeatureKind::kRejectedRobust) +
                           count_features(d, DebugFeatureKind::kRejectedRefine) >
                       0;
  }
  EXPECT_GT(tracked, 10);
  // Walking people: the estimators reject something on most tracked frames.
  EXPECT_GT(with_rejections, tracked / 2);
}

}  // namespace
}  // namespace rdslam
