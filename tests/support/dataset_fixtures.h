// Small self-made dataset fixtures for the frame-source tests: a temporary folder removed
// at the end of the test, random images, and exact frame comparison.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "core/frame_source.h"

namespace rdslam::testing {

class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("rdslam_" + std::string(info ? info->test_suite_name() : "t") + "_" +
             std::string(info ? info->name() : "t") + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::string str(const std::string& rel = "") const {
    return rel.empty() ? path_.string() : (path_ / rel).string();
  }
  // Writes `text` to `rel` (creating folders).
  std::string write(const std::string& rel, const std::string& text) const {
    const auto p = path_ / rel;
    std::filesystem::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }

 private:
  std::filesystem::path path_;
};

// A reproducible random image (`seed`), CV_8UC1 or CV_8UC3.
inline cv::Mat random_image(int width, int height, int type, uint64_t seed) {
  cv::Mat m(height, width, type);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

inline void write_png(const std::filesystem::path& p, const cv::Mat& m) {
  std::filesystem::create_directories(p.parent_path());
  ASSERT_TRUE(cv::imwrite(p.string(), m)) << p;
}

// Byte-exact image equality (size, type and every pixel).
inline ::testing::AssertionResult same_pixels(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) {
    return ::testing::AssertionFailure()
           << "size/type differ: " << a.cols << "x" << a.rows << " type " << a.type() << " vs "
           << b.cols << "x" << b.rows << " type " << b.type();
  }
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const int n = cv::countNonZero(diff.reshape(1));
  if (n != 0) return ::testing::AssertionFailure() << n << " pixel values differ";
  return ::testing::AssertionSuccess();
}

// Reads every frame of `src` (speed 0) into `frames`/`stamps`; fails on faults.
inline void read_all(FrameSource& src, std::vector<cv::Mat>& frames, std::vector<int64_t>& stamps) {
  Frame f;
  for (int guard = 0; guard < 100000; ++guard) {
    const SourceStatus st = src.read(f, 1000);
    if (st == SourceStatus::kEndOfStream) return;
    ASSERT_EQ(st, SourceStatus::kOk) << to_string(st);
    frames.push_back(f.image.clone());
    stamps.push_back(f.stamp_ns);
  }
  FAIL() << "source did not end";
}

}  // namespace rdslam::testing
