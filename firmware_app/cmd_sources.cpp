// `rdslam sources`: the cameras rdslam can open on this machine, with the formats, sizes and
// frame rates it can use (like `v4l2-ctl --list-formats-ext`, restricted to what rdslam
// decodes), and a ready-to-paste --set line per camera.
#include <cstdio>

#include "drivers/libcamera_source.h"
#include "drivers/v4l2_source.h"
#include "drivers/v4l2_syscalls.h"
#include "firmware_app/cli.h"
#include "firmware_app/commands.h"

namespace rdslam {

int cmd_sources(int argc, char** argv) {
  ArgParser p("rdslam sources",
              "List the live cameras rdslam can open: V4L2 devices (/dev/videoN) with the\n"
              "formats (MJPG, YUYV, GREY), sizes and frame rates rdslam can use"
#ifdef RDSLAM_HAVE_LIBCAMERA
              ", and the\ncameras libcamera sees"
#endif
              ". Recorded sources (tum:, euroc:, kitti:, images:,\nvideo:, lcm:) are described "
              "in docs/sources.md.");
  if (!p.parse(argc, argv)) return 0;
  std::printf("V4L2 devices:\n%s", describe_v4l2_devices(list_v4l2_devices(system_v4l2())).c_str());
#ifdef RDSLAM_HAVE_LIBCAMERA
  const auto cams = list_libcamera_cameras();
  std::printf("\nlibcamera cameras:\n");
  if (cams.empty()) std::printf("none (libcamera finds no camera on this machine)\n");
  for (const auto& c : cams)
    std::printf("%s\n    use: --set source=libcamera:%s\n", c.c_str(),
                c.substr(0, c.find(':')).c_str());
#else
  std::printf("\nlibcamera: not built in (install libcamera-dev and rebuild)\n");
#endif
  return 0;
}

}  // namespace rdslam
