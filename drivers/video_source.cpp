#include "drivers/video_source.h"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <opencv2/videoio.hpp>
#include <stdexcept>

namespace rdslam {

namespace {

class VideoSequence : public RecordedSequence {
 public:
  VideoSequence(cv::VideoCapture cap, int64_t count, double fps, int width, int height)
      : cap_(std::move(cap)), count_(count), fps_(fps), width_(width), height_(height) {}

  bool stamp(int64_t index, int64_t& stamp_ns) const override {
    if (index < 0 || (count_ > 0 && index >= count_) || ended_at_ <= index) return false;
    stamp_ns = std::llround(static_cast<double>(index) * 1e9 / fps_);
    return true;
  }

  SourceStatus load(int64_t index, cv::Mat& image) override {
    // Sequential access: grab (demux + decode, no colour conversion) up to `index`.
    while (pos_ <= index) {
      if (!cap_.grab()) {
        ended_at_ = pos_;
        return SourceStatus::kEndOfStream;
      }
      ++pos_;
    }
    if (pos_ != index + 1) return SourceStatus::kFault;  // indices must increase
    // retrieve() writes into `image`, reusing it when it already has this size and type.
    if (!cap_.retrieve(image) || image.cols != width_ || image.rows != height_ ||
        image.type() != CV_8UC3) {
      return SourceStatus::kFault;
    }
    return SourceStatus::kOk;
  }

 private:
  cv::VideoCapture cap_;
  int64_t count_;
  double fps_;
  int width_, height_;
  int64_t pos_ = 0;  // frames grabbed so far
  int64_t ended_at_ = INT64_MAX;
};

}  // namespace

bool has_video_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  for (const char* e : {".avi", ".mp4", ".mkv", ".mov", ".webm", ".m4v", ".mpg", ".mpeg", ".ogv"}) {
    if (ext == e) return true;
  }
  return false;
}

std::unique_ptr<ReplaySource> open_video_source(const std::string& uri, const std::string& path,
                                                double fps_override, double speed) {
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error(path + ": no such file");
  cv::VideoCapture cap(path, cv::CAP_FFMPEG);
  if (!cap.isOpened()) throw std::runtime_error(path + ": cannot open as a video (FFmpeg)");
  SourceInfo info;
  info.uri = uri;
  info.kind = "video";
  info.format = PixelFormat::kBgr8;
  info.width = static_cast<int>(cap.get(cv::CAP_PROP_FRAME_WIDTH));
  info.height = static_cast<int>(cap.get(cv::CAP_PROP_FRAME_HEIGHT));
  const double fps = fps_override > 0.0 ? fps_override : cap.get(cv::CAP_PROP_FPS);
  if (!(fps > 0.0 && fps < 1e4)) {
    throw std::runtime_error(path + ": the container has no frame rate; give one with " +
                             "video:FILE?fps=N");
  }
  if (info.width <= 0 || info.height <= 0) throw std::runtime_error(path + ": no frame size");
  info.nominal_fps = fps;
  const double count = cap.get(cv::CAP_PROP_FRAME_COUNT);
  info.frame_count = count >= 1.0 ? static_cast<int64_t>(count) : -1;
  auto seq = std::make_unique<VideoSequence>(std::move(cap), info.frame_count, fps, info.width,
                                             info.height);
  return std::make_unique<ReplaySource>(std::move(seq), std::move(info), std::nullopt, std::nullopt,
                                        speed);
}

}  // namespace rdslam
