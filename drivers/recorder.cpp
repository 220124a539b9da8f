#include "drivers/recorder.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "core/timestamp.h"
#include "drivers/replay_source.h"

namespace rdslam {

namespace fs = std::filesystem;

namespace {

bool write_all(int fd, const void* data, size_t len) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (len > 0) {
    const ssize_t n = ::write(fd, p, len);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    len -= static_cast<size_t>(n);
  }
  return true;
}

}  // namespace

TumRecorder::TumRecorder(const std::string& dir, const std::string& source_uri,
                         const std::optional<CameraModel>& camera)
    : dir_(dir) {
  std::error_code ec;
  if (fs::exists(dir_, ec)) {
    if (!fs::is_directory(dir_) || !fs::is_empty(dir_)) {
      throw std::runtime_error(dir_ + ": exists and is not an empty folder; refusing to overwrite");
    }
  }
  fs::create_directories(fs::path(dir_) / "rgb", ec);
  if (ec) throw std::runtime_error(dir_ + ": cannot create: " + ec.message());
  const std::string list = (fs::path(dir_) / "rgb.txt").string();
  list_fd_ = ::open(list.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_APPEND | O_CLOEXEC, 0644);
  if (list_fd_ < 0) throw std::runtime_error(list + ": cannot create: " + std::strerror(errno));
  const std::string header =
      "# color images\n# recorded by rdslam record from " + source_uri + "\n# timestamp filename\n";
  if (!write_all(list_fd_, header.data(), header.size())) {
    throw std::runtime_error(list + ": write failed: " + std::strerror(errno));
  }
  if (camera) write_camera_yaml((fs::path(dir_) / "camera.yaml").string(), *camera);
  // Fast zlib level: recording must keep up with the camera; PNG stays lossless.
  png_params_ = {cv::IMWRITE_PNG_COMPRESSION, 1};
}

TumRecorder::~TumRecorder() {
  close();
}

bool TumRecorder::write(const Frame& frame) {
  if (list_fd_ < 0 || frame.image.empty()) {
    ++failures_;
    return false;
  }
  // Two frames with one stamp would share a file name: keep the first, name later ones
  // "<stamp>_<seq>.png" so nothing is overwritten.
  std::string name = "rgb/" + format_seconds_ns(frame.stamp_ns);
  if (written_ > 0 && frame.stamp_ns == last_stamp_ns_) name += "_" + std::to_string(frame.seq);
  name += ".png";
  const fs::path final_path = fs::path(dir_) / name;
  const std::string tmp = final_path.string() + ".tmp";
  try {
    if (!cv::imencode(".png", frame.image, png_, png_params_)) {
      ++failures_;
      return false;
    }
  } catch (const cv::Exception&) {
    ++failures_;
    return false;
  }
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bool ok = fd >= 0 && write_all(fd, png_.data(), png_.size());
  if (fd >= 0) ok = (::close(fd) == 0) && ok;
  std::error_code ec;
  if (ok && fs::exists(final_path, ec)) ok = false;  // never replace an earlier frame
  if (ok) ok = std::rename(tmp.c_str(), final_path.c_str()) == 0;
  if (!ok) {
    ::unlink(tmp.c_str());
    ++failures_;
    return false;
  }
  const std::string line = format_seconds_ns(frame.stamp_ns) + " " + name + "\n";
  if (!write_all(list_fd_, line.data(), line.size())) {
    ++failures_;
    return false;
  }
  last_stamp_ns_ = frame.stamp_ns;
  ++written_;
  bytes_ += png_.size();
  return true;
}

void TumRecorder::close() {
  if (list_fd_ < 0) return;
  ::fsync(list_fd_);
  ::close(list_fd_);
  list_fd_ = -1;
}

}  // namespace rdslam
