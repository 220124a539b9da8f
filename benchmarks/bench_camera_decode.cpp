// Per-frame cost of the live-camera paths (drivers/mjpeg_decoder.h, drivers/yuyv.h): MJPEG
// decode and YUYV conversion of a real 640x480 frame (vtest.avi through ffmpeg, as in the
// unit tests) into a preallocated grey or BGR image. Sizes the capture thread's budget on
// the target board:  ./build/benchmarks/bench_camera_decode
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "drivers/mjpeg_decoder.h"
#include "drivers/yuyv.h"

namespace {

constexpr int kW = 640;
constexpr int kH = 480;

struct Footage {
  std::vector<uint8_t> jpeg, yuyv;
  std::string error;
};

std::vector<uint8_t> slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

const Footage& footage() {
  static const Footage f = [] {
    Footage out;
    std::string src = "/usr/share/doc/opencv-doc/examples/data/vtest.avi";
    if (!std::filesystem::exists(src)) src = RDSLAM_SHARED_DIR "/data/opencv_vtest/vtest.avi";
    if (!std::filesystem::exists(src)) {
      out.error = "vtest.avi not found";
      return out;
    }
    const std::string dir = std::filesystem::temp_directory_path().string() + "/rdslam_bench_" +
                            std::to_string(getpid());
    std::filesystem::create_directories(dir);
    const std::string common = "ffmpeg -nostdin -v error -y -i " + src +
                               " -frames:v 1 -vf scale=" + std::to_string(kW) + ":" +
                               std::to_string(kH) + " ";
    if (std::system((common + "-c:v mjpeg -pix_fmt yuvj422p -q:v 3 " + dir + "/f.jpg").c_str()) ||
        std::system((common + "-pix_fmt yuyv422 -f rawvideo " + dir + "/f.yuyv").c_str())) {
      out.error = "ffmpeg failed";
    } else {
      out.jpeg = slurp(dir + "/f.jpg");
      out.yuyv = slurp(dir + "/f.yuyv");
    }
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    return out;
  }();
  return f;
}

void BM_MjpegDecode(benchmark::State& state) {
  const Footage& f = footage();
  if (!f.error.empty()) {
    state.SkipWithError(f.error.c_str());
    return;
  }
  rdslam::MjpegDecoder dec;
  cv::Mat out(kH, kW, state.range(0) ? CV_8UC3 : CV_8UC1);
  for (auto _ : state) {
    if (dec.decode(f.jpeg.data(), f.jpeg.size(), out) != rdslam::DecodeStatus::kOk) {
      state.SkipWithError("decode failed");
      break;
    }
    benchmark::DoNotOptimize(out.data);
  }
  state.SetLabel(std::string(state.range(0) ? "bgr" : "grey") + ", " +
                 std::to_string(f.jpeg.size() / 1024) + " KiB JPEG");
}
BENCHMARK(BM_MjpegDecode)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_YuyvConvert(benchmark::State& state) {
  const Footage& f = footage();
  if (!f.error.empty()) {
    state.SkipWithError(f.error.c_str());
    return;
  }
  cv::Mat out(kH, kW, state.range(0) ? CV_8UC3 : CV_8UC1);
  for (auto _ : state) {
    rdslam::yuyv_to_image(f.yuyv.data(), f.yuyv.size(), kW, kH, kW * 2, out);
    benchmark::DoNotOptimize(out.data);
  }
  state.SetLabel(state.range(0) ? "bgr" : "grey");
}
BENCHMARK(BM_YuyvConvert)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
