// `rdslam sources` end to end: the real binary on this machine. Without cameras (as in CI)
// it must say so clearly and exit 0; with cameras it must list them with a usable --set line.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <string>

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

}  // namespace
}  // namespace rdslam
