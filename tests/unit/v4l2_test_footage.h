// Test helper for the V4L2/MJPEG/YUYV tests: makes REAL camera-like frames at test time with
// ffmpeg from OpenCV's vtest.avi (Debian opencv-doc, or ../shared/data/opencv_vtest), plus
// ffmpeg's own BGR/grey decode of the same frames as the reference. Header-only, used by
// tests/unit/test_mjpeg_decoder.cpp and test_v4l2_*.cpp.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace rdslam::testing {

inline std::string vtest_path() {
  const char* candidates[] = {"/usr/share/doc/opencv-doc/examples/data/vtest.avi",
                              RDSLAM_SHARED_DIR "/data/opencv_vtest/vtest.avi"};
  for (const char* c : candidates) {
    if (std::filesystem::exists(c)) return c;
  }
  return "";
}

inline bool have_ffmpeg() {
  return std::system("ffmpeg -version >/dev/null 2>&1") == 0;
}

// Empty string when footage cannot be made; `why` then says what is missing.
inline std::string footage_unavailable() {
  if (vtest_path().empty()) {
    return "vtest.avi not found (install Debian opencv-doc or provide ../shared/data/opencv_vtest)";
  }
  if (!have_ffmpeg()) return "ffmpeg not installed (toolchain/install-deps.sh installs it)";
  return "";
}

class TempDir {
 public:
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "rdslam_v4l2_XXXXXX").string();
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    const char* p = mkdtemp(buf.data());
    path_ = p ? p : "";
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

inline bool run(const std::string& cmd) {
  const int rc = std::system((cmd + " >/dev/null 2>&1").c_str());
  return rc == 0;
}

inline std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

// vtest.avi is 768x576; scaled to a common webcam size keeps the tests fast.
constexpr int kW = 640;
constexpr int kH = 480;
constexpr int kFrames = 3;

inline std::string scale_filter() {
  return "-vf scale=" + std::to_string(kW) + ":" + std::to_string(kH) + ":flags=bicubic";
}

// kFrames JPEGs with 4:2:2 chroma (what UVC webcams send): dir/f01.jpg ...
inline bool make_mjpeg_frames(const TempDir& dir) {
  return run("ffmpeg -nostdin -v error -y -i " + vtest_path() + " -frames:v " +
             std::to_string(kFrames) + " " + scale_filter() +
             " -c:v mjpeg -pix_fmt yuvj422p -q:v 3 -f image2 " + dir.file("f%02d.jpg"));
}

inline std::string jpeg_name(int i) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "f%02d.jpg", i + 1);
  return buf;
}

// ffmpeg's own decode of the JPEGs: pix_fmt bgr24 or gray, concatenated raw frames.
inline bool decode_jpegs_with_ffmpeg(const TempDir& dir, const std::string& pix_fmt,
                                     const std::string& out_name) {
  return run("ffmpeg -nostdin -v error -y -i " + dir.file("f%02d.jpg") + " -f rawvideo -pix_fmt " +
             pix_fmt + " " + dir.file(out_name));
}

// kFrames raw YUYV (yuyv422) frames, concatenated, and ffmpeg's conversion of them.
inline bool make_yuyv_frames(const TempDir& dir) {
  return run("ffmpeg -nostdin -v error -y -i " + vtest_path() + " -frames:v " +
             std::to_string(kFrames) + " " + scale_filter() + " -pix_fmt yuyv422 -f rawvideo " +
             dir.file("yuyv.raw"));
}

inline bool convert_yuyv_with_ffmpeg(const TempDir& dir, const std::string& pix_fmt,
                                     const std::string& out_name) {
  return run("ffmpeg -nostdin -v error -y -f rawvideo -pix_fmt yuyv422 -s " + std::to_string(kW) +
             "x" + std::to_string(kH) + " -i " + dir.file("yuyv.raw") + " -f rawvideo -pix_fmt " +
             pix_fmt + " " + dir.file(out_name));
}

}  // namespace rdslam::testing
