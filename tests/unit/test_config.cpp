#include <gtest/gtest.h>

#include "firmware_app/config.h"

using rdslam::ConfigError;
using rdslam::load_config;

TEST(Config, DefaultsLoad) {
  auto cfg = load_config("", {});
  EXPECT_EQ(cfg.camera.width, 640);
  EXPECT_EQ(cfg.lcm.url, "udpm://239.255.76.67:7667?ttl=0");
}
