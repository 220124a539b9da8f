// libcamera source; compiled only when CMake finds libcamera (drivers/CMakeLists.txt).
// See drivers/libcamera_source.h for the contract.
#include "drivers/libcamera_source.h"

#include <libcamera/libcamera.h>
#include <sys/mman.h>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>

#include "core/log.h"
#include "drivers/mjpeg_decoder.h"

namespace rdslam {
namespace {

namespace lc = libcamera;

constexpr int kMaxRequests = 16;

// libcamera logs INFO/WARN lines (e.g. "No IPA found") to stderr by default, which would
// interleave with rdslam's journald-formatted log; keep its errors only, unless the user
// asked for more with libcamera's own LIBCAMERA_LOG_LEVELS.
void quiet_libcamera_log() {
  if (std::getenv("LIBCAMERA_LOG_LEVELS")) return;
  // The environment is read when libcamera's logger starts (categories registered later do
  // not see logSetLevel); set both so either order works. Capture/start-up thread only.
  setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);
  lc::logSetLevel("*", "ERROR");
}  // LibcameraParams::buffers is limited to this

struct Candidate {
  lc::PixelFormat format;
  LibcameraLayout layout;
};

// Preference order: formats with a full-resolution luma plane first (cheapest to turn into
// the tracker's grey image), MJPEG last (USB cameras behind libcamera's UVC pipeline).
const Candidate kCandidates[] = {
    {lc::formats::R8, LibcameraLayout::kGrey},   {lc::formats::YUV420, LibcameraLayout::kYuv420},
    {lc::formats::NV12, LibcameraLayout::kNv12}, {lc::formats::NV21, LibcameraLayout::kNv21},
    {lc::formats::YUYV, LibcameraLayout::kYuyv}, {lc::formats::MJPEG, LibcameraLayout::kMjpeg},
};

class LibcameraSource final : public FrameSource {
 public:
  LibcameraSource(const std::string& which, const LibcameraParams& params, int default_width,
                  int default_height);
  ~LibcameraSource() override { shutdown(); }
  SourceStatus read(Frame& out, int timeout_ms) override;
  const SourceInfo& info() const override { return info_; }
  SourceCounters counters() const override {
    SourceCounters c;
    c.delivered = delivered_.load(std::memory_order_relaxed);
    c.faults = faults_.load(std::memory_order_relaxed);
    c.timeouts = timeouts_.load(std::memory_order_relaxed);
    c.skipped = skipped_.load(std::memory_order_relaxed);
    return c;
  }

 private:
  struct PlaneView {
    const uint8_t* data = nullptr;
    size_t length = 0;
  };
  struct BufferMap {
    std::array<PlaneView, 3> planes{};
    int plane_count = 0;
  };

  [[noreturn]] void fail(const std::string& what) {
    shutdown();
    throw std::runtime_error("libcamera:" + which_ + ": " + what);
  }
  void map_buffers();
  void on_request_completed(lc::Request* request);  // libcamera's thread
  void recycle(lc::Request* request);
  SourceStatus convert(lc::Request* request, Frame& out);
  void shutdown();

  std::string which_;
  LibcameraParams params_;
  SourceInfo info_;
  std::unique_ptr<lc::CameraManager> manager_;
  std::shared_ptr<lc::Camera> camera_;
  bool acquired_ = false;
  bool started_ = false;
  std::unique_ptr<lc::CameraConfiguration> config_;
  lc::Stream* stream_ = nullptr;
  std::unique_ptr<lc::FrameBufferAllocator> allocator_;
  std::vector<std::unique_ptr<lc::Request>> requests_;
  std::map<const lc::FrameBuffer*, BufferMap> maps_;
  std::vector<std::pair<void*, size_t>> mmaps_;
  LibcameraLayout layout_ = LibcameraLayout::kYuv420;
  bool limited_range_ = true;
  int width_ = 0;
  int height_ = 0;
  size_t strides_[3] = {0, 0, 0};
  int out_type_ = CV_8UC1;
  MjpegDecoder decoder_;
  uint64_t seq_ = 0;

  // Completed requests, oldest first; capacity >= requests in flight, so push never fails.
  std::mutex mu_;
  std::condition_variable cv_;
  std::array<lc::Request*, kMaxRequests> done_{};
  int done_count_ = 0;

  std::atomic<uint64_t> delivered_{0}, faults_{0}, timeouts_{0}, skipped_{0};
};

LibcameraSource::LibcameraSource(const std::string& which, const LibcameraParams& params,
                                 int default_width, int default_height)
    : which_(which), params_(params) {
  quiet_libcamera_log();
  manager_ = std::make_unique<lc::CameraManager>();
  if (manager_->start() != 0) fail("CameraManager::start failed");
  const auto cams = manager_->cameras();
  if (cams.empty()) fail("libcamera finds no cameras on this machine");
  char* end = nullptr;
  const long index = std::strtol(which.c_str(), &end, 10);
  if (!which.empty() && end && *end == '\0') {
    if (index < 0 || index >= static_cast<long>(cams.size())) {
      fail("no camera with index " + which + " (" + std::to_string(cams.size()) + " found)");
    }
    camera_ = cams[static_cast<size_t>(index)];
  } else {
    camera_ = manager_->get(which);
    if (!camera_) fail("no camera with id '" + which + "'");
  }
  if (camera_->acquire() != 0) fail("camera is in use by another process");
  acquired_ = true;

  width_ = params.width > 0 ? params.width : default_width;
  height_ = params.height > 0 ? params.height : default_height;
  bool chosen = false;
  for (const Candidate& c : kCandidates) {
    config_ = camera_->generateConfiguration({lc::StreamRole::VideoRecording});
    if (!config_ || config_->size() != 1) fail("cannot generate a one-stream configuration");
    lc::StreamConfiguration& sc = config_->at(0);
    sc.pixelFormat = c.format;
    sc.size = lc::Size(static_cast<unsigned>(width_), static_cast<unsigned>(height_));
    sc.bufferCount = static_cast<unsigned>(params.buffers);
    if (config_->validate() == lc::CameraConfiguration::Invalid) continue;
    if (sc.pixelFormat != c.format) continue;  // adjusted to a format we did not ask for
    layout_ = c.layout;
    chosen = true;
    break;
  }
  if (!chosen) fail("the camera offers none of R8, YUV420, NV12, NV21, YUYV, MJPEG");
  lc::StreamConfiguration& sc = config_->at(0);
  if (static_cast<int>(sc.size.width) != width_ || static_cast<int>(sc.size.height) != height_) {
    RDSLAM_LOG_WARN("libcamera:%s: requested %dx%d, camera delivers %ux%u (set camera.* to match)",
                    which.c_str(), width_, height_, sc.size.width, sc.size.height);
    width_ = static_cast<int>(sc.size.width);
    height_ = static_cast<int>(sc.size.height);
  }
  if (camera_->configure(config_.get()) != 0) fail("Camera::configure failed");
  stream_ = sc.stream();
  limited_range_ = !sc.colorSpace || sc.colorSpace->range == lc::ColorSpace::Range::Limited;
  // Plane strides: luma stride from libcamera; chroma planes of the 4:2:0 layouts follow it.
  strides_[0] = sc.stride;
  strides_[1] = layout_ == LibcameraLayout::kYuv420 ? sc.stride / 2 : sc.stride;
  strides_[2] = sc.stride / 2;

  allocator_ = std::make_unique<lc::FrameBufferAllocator>(camera_);
  if (allocator_->allocate(stream_) < 0) fail("cannot allocate frame buffers");
  const auto& buffers = allocator_->buffers(stream_);
  if (buffers.empty() || buffers.size() > static_cast<size_t>(kMaxRequests)) {
    fail("allocator returned " + std::to_string(buffers.size()) + " buffers");
  }
  map_buffers();
  for (size_t i = 0; i < buffers.size(); ++i) {
    std::unique_ptr<lc::Request> r = camera_->createRequest(i);
    if (!r || r->addBuffer(stream_, buffers[i].get()) != 0) fail("cannot create requests");
    requests_.push_back(std::move(r));
  }
  camera_->requestCompleted.connect(this, &LibcameraSource::on_request_completed);
  lc::ControlList controls(lc::controls::controls);
  const int64_t frame_us = static_cast<int64_t>(1e6 / params.fps);
  controls.set(lc::controls::FrameDurationLimits, lc::Span<const int64_t, 2>({frame_us, frame_us}));
  if (camera_->start(&controls) != 0) fail("Camera::start failed");
  started_ = true;
  for (auto& r : requests_) {
    if (camera_->queueRequest(r.get()) != 0) fail("Camera::queueRequest failed");
  }
  out_type_ = params.output == "bgr" ? CV_8UC3 : CV_8UC1;
  info_.uri = "libcamera:" + which;
  info_.kind = "libcamera";
  info_.width = width_;
  info_.height = height_;
  info_.format = out_type_ == CV_8UC3 ? PixelFormat::kBgr8 : PixelFormat::kGray8;
  info_.nominal_fps = params.fps;
  info_.live = true;
  RDSLAM_LOG_INFO("libcamera:%s: %s streaming %s %dx%d, %zu requests, %s range", which.c_str(),
                  camera_->id().c_str(), sc.pixelFormat.toString().c_str(), width_, height_,
                  requests_.size(), limited_range_ ? "limited" : "full");
}

void LibcameraSource::map_buffers() {
  // Planes of one buffer usually share one dmabuf at different offsets: map each fd once.
  for (const auto& buffer : allocator_->buffers(stream_)) {
    std::map<int, std::pair<uint8_t*, size_t>> by_fd;
    for (const auto& plane : buffer->planes()) {
      const int fd = plane.fd.get();
      size_t& len = by_fd[fd].second;
      len = std::max(len, static_cast<size_t>(plane.offset) + plane.length);
    }
    for (auto& [fd, m] : by_fd) {
      void* p = mmap(nullptr, m.second, PROT_READ, MAP_SHARED, fd, 0);
      if (p == MAP_FAILED) fail(std::string("mmap of a frame buffer failed: ") + strerror(errno));
      mmaps_.emplace_back(p, m.second);
      m.first = static_cast<uint8_t*>(p);
    }
    BufferMap bm;
    for (const auto& plane : buffer->planes()) {
      if (bm.plane_count >= 3) break;
      bm.planes[bm.plane_count++] = {by_fd[plane.fd.get()].first + plane.offset, plane.length};
    }
    maps_[buffer.get()] = bm;
  }
}

void LibcameraSource::on_request_completed(lc::Request* request) {
  if (request->status() == lc::Request::RequestCancelled) return;  // stopping
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (done_count_ < kMaxRequests) done_[done_count_++] = request;
  }
  cv_.notify_one();
}

void LibcameraSource::recycle(lc::Request* request) {
  request->reuse(lc::Request::ReuseBuffers);
  if (started_) camera_->queueRequest(request);
}

SourceStatus LibcameraSource::convert(lc::Request* request, Frame& out) {
  lc::FrameBuffer* buffer = request->findBuffer(stream_);
  if (!buffer || buffer->metadata().status != lc::FrameMetadata::FrameSuccess) {
    return SourceStatus::kFault;
  }
  const auto it = maps_.find(buffer);
  if (it == maps_.end()) return SourceStatus::kFault;
  const BufferMap& bm = it->second;
  const auto used = buffer->metadata().planes();
  const uint8_t* planes[3] = {nullptr, nullptr, nullptr};
  size_t bytes[3] = {0, 0, 0};
  for (int i = 0; i < bm.plane_count; ++i) {
    planes[i] = bm.planes[i].data;
    bytes[i] = bm.planes[i].length;
    if (static_cast<size_t>(i) < used.size())
      bytes[i] = std::min<size_t>(bytes[i], used[i].bytesused);
  }
  // Single-plane 4:2:0 buffers: split the luma/chroma planes by stride x height.
  if (bm.plane_count == 1 &&
      (layout_ == LibcameraLayout::kYuv420 || layout_ == LibcameraLayout::kNv12 ||
       layout_ == LibcameraLayout::kNv21)) {
    const size_t luma = strides_[0] * static_cast<size_t>(height_);
    if (bytes[0] < luma) return SourceStatus::kFault;
    const size_t chroma = strides_[1] * static_cast<size_t>((height_ + 1) / 2);
    planes[1] = planes[0] + luma;
    bytes[1] = bytes[0] - luma;
    if (layout_ == LibcameraLayout::kYuv420) {
      planes[2] = planes[1] + chroma;
      bytes[2] = bytes[1] > chroma ? bytes[1] - chroma : 0;
    }
    bytes[0] = luma;
  }
  if (layout_ == LibcameraLayout::kMjpeg) {
    return decoder_.decode(planes[0], bytes[0], out.image) == DecodeStatus::kOk
               ? SourceStatus::kOk
               : SourceStatus::kFault;
  }
  return convert_libcamera_frame(layout_, planes, bytes, strides_, width_, height_, limited_range_,
                                 out.image)
             ? SourceStatus::kOk
             : SourceStatus::kFault;
}

SourceStatus LibcameraSource::read(Frame& out, int timeout_ms) {
  if (out.image.rows != height_ || out.image.cols != width_ || out.image.type() != out_type_) {
    out.image.create(height_, width_, out_type_);
  }
  std::array<lc::Request*, kMaxRequests> got{};
  int n = 0;
  {
    std::unique_lock<std::mutex> lock(mu_);
    if (!cv_.wait_for(lock, std::chrono::milliseconds(std::max(0, timeout_ms)),
                      [this] { return done_count_ > 0; })) {
      timeouts_.fetch_add(1, std::memory_order_relaxed);
      return SourceStatus::kTimeout;
    }
    n = done_count_;
    std::copy_n(done_.begin(), n, got.begin());
    done_count_ = 0;
  }
  // Newest wins: older completed requests go straight back to the camera, counted.
  for (int i = 0; i + 1 < n; ++i) {
    recycle(got[i]);
    skipped_.fetch_add(1, std::memory_order_relaxed);
  }
  lc::Request* r = got[n - 1];
  const SourceStatus st = convert(r, out);
  if (st == SourceStatus::kOk) {
    const lc::FrameBuffer* buffer = r->findBuffer(stream_);
    // SensorTimestamp (start of exposure of the first line) when the pipeline reports it,
    // else the buffer's kernel timestamp; both CLOCK_MONOTONIC ns.
    const std::optional<int64_t> sensor = r->metadata().get(lc::controls::SensorTimestamp);
    out.stamp_ns = sensor ? *sensor : static_cast<int64_t>(buffer->metadata().timestamp);
    out.arrival_mono_ns = mono_now_ns();
    out.format = out_type_ == CV_8UC3 ? PixelFormat::kBgr8 : PixelFormat::kGray8;
    out.seq = seq_++;
    out.dataset_index = -1;
    delivered_.fetch_add(1, std::memory_order_relaxed);
  } else {
    faults_.fetch_add(1, std::memory_order_relaxed);
  }
  recycle(r);
  return st;
}

void LibcameraSource::shutdown() {
  if (started_ && camera_) camera_->stop();  // cancels outstanding requests
  started_ = false;
  if (camera_) camera_->requestCompleted.disconnect(this);
  requests_.clear();
  for (auto& [p, len] : mmaps_) munmap(p, len);
  mmaps_.clear();
  maps_.clear();
  if (allocator_ && stream_) allocator_->free(stream_);
  allocator_.reset();
  config_.reset();
  if (acquired_ && camera_) camera_->release();
  acquired_ = false;
  camera_.reset();
  if (manager_) manager_->stop();
  manager_.reset();
}

}  // namespace

std::unique_ptr<FrameSource> open_libcamera_source(const std::string& which,
                                                   const LibcameraParams& params, int default_width,
                                                   int default_height) {
  return std::make_unique<LibcameraSource>(which, params, default_width, default_height);
}

std::vector<std::string> list_libcamera_cameras() {
  quiet_libcamera_log();
  lc::CameraManager manager;
  std::vector<std::string> out;
  if (manager.start() != 0) return out;
  const auto cams = manager.cameras();
  for (size_t i = 0; i < cams.size(); ++i) {
    std::string model;
    if (const auto m = cams[i]->properties().get(lc::properties::Model)) model = *m;
    out.push_back(std::to_string(i) + ": " + cams[i]->id() +
                  (model.empty() ? "" : " (" + model + ")"));
  }
  manager.stop();
  return out;
}

}  // namespace rdslam
