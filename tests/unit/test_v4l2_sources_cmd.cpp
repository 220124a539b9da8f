// `rdslam sources` end to end: the real binary on this machine. Without cameras (as in CI)
// it must say so clearly and exit 0; with cameras it must list them with a usable --set line.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <string>

#include "drivers/source_factory.h"
#include "drivers/v4l2_source.h"
#include "drivers/v4l2_syscalls.h"

namespace rdslam {
namespace {

std::string run_capture(const std::string& cmd, int& rc) {
  std::string out;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) {
    rc = -1;
    return out;
  }
  std::array<char, 4096> buf{};
  while (size_t n = fread(buf.data(), 1, buf.size(), p)) out.append(buf.data(), n);
  rc = pclose(p);
  return out;
}

TEST(RdslamSources, ListsCamerasOrSaysThereAreNone) {
  int rc = 0;
  const std::string out = run_capture(std::string(RDSLAM_BINARY) + " sources", rc);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("V4L2 devices:"), std::string::npos) << out;
  const auto devices = list_v4l2_devices(system_v4l2());
  bool usable = false;
  for (const auto& d : devices) {
    for (const auto& f : d.formats) usable = usable || (d.capture && f.usable);
  }
  if (usable) {
    EXPECT_NE(out.find("use: --set source=v4l2:"), std::string::npos) << out;
  } else {
    EXPECT_NE(out.find("no V4L2"), std::string::npos) << out;
  }
#ifdef RDSLAM_HAVE_LIBCAMERA
  EXPECT_NE(out.find("libcamera cameras:"), std::string::npos) << out;
#else
  EXPECT_NE(out.find("libcamera: not built in"), std::string::npos) << out;
#endif
}

TEST(RdslamSources, HelpDescribesTheCommand) {
  int rc = 0;
  const std::string out = run_capture(std::string(RDSLAM_BINARY) + " sources --help", rc);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("formats (MJPG, YUYV, GREY)"), std::string::npos) << out;
}

std::string open_error(const std::string& uri) {
  static const SourceOptions defaults;
  try {
    open_source(uri, defaults);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(V4l2Factory, MissingOrNonV4l2DevicesFailAtStartupNamingTheDevice) {
  const std::string missing = open_error("v4l2:/dev/rdslam-no-such-camera");
  EXPECT_NE(missing.find("v4l2:/dev/rdslam-no-such-camera: open: No such file or directory"),
            std::string::npos)
      << missing;
  // A character device is auto-detected as v4l2:, and /dev/null is not a camera.
  const std::string not_v4l2 = open_error("/dev/null");
  EXPECT_NE(not_v4l2.find("v4l2:/dev/null: VIDIOC_QUERYCAP"), std::string::npos) << not_v4l2;
  EXPECT_NE(not_v4l2.find("not a V4L2 device"), std::string::npos) << not_v4l2;
  // Bad v4l2 settings are refused before the device is touched.
  SourceOptions o;
  o.v4l2.width = 640;  // height left 0
  try {
    open_source("v4l2:/dev/null", o);
    ADD_FAILURE() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("v4l2.width/v4l2.height"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rdslam
