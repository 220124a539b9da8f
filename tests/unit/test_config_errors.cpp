// Bad configurations, from files and from --set, each with the exact message the user sees:
// the key, the value and what is allowed (issue 3, item 5).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "firmware_app/config.h"

namespace fs = std::filesystem;

namespace {

class ConfigErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("rdslam_config_errors_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes `yaml` to a file in the test's directory and returns its path.
  std::string file(const std::string& yaml) {
    const fs::path p = dir_ / "rdslam.yaml";
    std::ofstream(p) << yaml;
    return p.string();
  }

  // The ConfigError message of loading `path` with `overrides`, or "(loaded)".
  static std::string error_of(const std::string& path, const std::vector<std::string>& overrides) {
    try {
      rdslam::load_config(path, overrides);
    } catch (const rdslam::ConfigError& e) {
      return e.what();
    }
    return "(loaded)";
  }

  fs::path dir_;
};

}  // namespace

TEST_F(ConfigErrors, ValidFileAndOverridesLoad) {
  // The control: the same mechanisms accept good values, so the errors below are specific.
  const std::string path = file("camera:\n  fx: 600\n  model: pinhole-equidistant\n");
  EXPECT_EQ(error_of(path, {"camera.fy=610", "lcm.publish_bot_core_pose=true"}), "(loaded)");
  const rdslam::AppConfig cfg = rdslam::load_config(path, {"camera.fy=610"});
  EXPECT_EQ(cfg.camera.fx, 600.0);
  EXPECT_EQ(cfg.camera.fy, 610.0);
  EXPECT_EQ(cfg.camera.model, "pinhole-equidistant");
}

TEST_F(ConfigErrors, FileValueOutOfRange) {
  EXPECT_EQ(error_of(file("camera:\n  fx: -3\n"), {}),
            "config: camera.fx: value '-3' is out of range; allowed [1, 100000]");
}

TEST_F(ConfigErrors, FileIntegerOutOfRange) {
  EXPECT_EQ(error_of(file("camera:\n  width: 9000\n"), {}),
            "config: camera.width: value '9000' is out of range; allowed [16, 8192]");
}

TEST_F(ConfigErrors, FileUnknownKeyInSection) {
  EXPECT_EQ(error_of(file("camera:\n  fxx: 500\n"), {}),
            "config: unknown key 'camera.fxx'; allowed in camera: model, width, height, fx, fy, "
            "cx, cy, k1, k2, p1, p2, k3, k4");
}

// Found by tests/fuzz/fuzz_config.cpp: YAML allows a mapping or a sequence as a key ("? ...");
// it is a ConfigError naming where, not a yaml-cpp conversion exception escaping load_config.
TEST_F(ConfigErrors, KeyThatIsNotAPlainName) {
  EXPECT_EQ(error_of(file("camera:\n? fx: 1\n: 2\n"), {}),
            "config: top level: a key that is not a plain name (line 2)");
  EXPECT_EQ(error_of(file("camera:\n  ? [fx, fy]\n  : 500\n"), {}),
            "config: camera: a key that is not a plain name (line 2)");
}

TEST_F(ConfigErrors, FileUnknownTopLevelKey) {
  // The allowed list names every registered section and top-level key, sorted; it grows as
  // modules register sections, so it is taken from the configuration itself.
  rdslam::AppConfig cfg;
  std::set<std::string> keys = {"source", "log_level"};
  for (const auto& s : cfg.sections()) {
    if (s.key[0] != '\0') keys.insert(s.key);
  }
  std::string allowed;
  for (const auto& k : keys) allowed += (allowed.empty() ? "" : ", ") + k;
  ASSERT_NE(allowed.find("camera, "), std::string::npos);
  EXPECT_EQ(error_of(file("sauce: tum:/data\n"), {}),
            "config: unknown key 'sauce'; allowed at top level: " + allowed);
}

TEST_F(ConfigErrors, FileValueNotInAllowedSet) {
  EXPECT_EQ(error_of(file("camera:\n  model: fisheye\n"), {}),
            "config: camera.model: value 'fisheye' is not allowed; allowed one of: "
            "pinhole-radtan, pinhole-equidistant");
}

TEST_F(ConfigErrors, FileListWhereANumberIsExpected) {
  EXPECT_EQ(error_of(file("camera:\n  fx: [500, 510]\n"), {}),
            "config: camera.fx: expected a single value, not a list or mapping");
}

TEST_F(ConfigErrors, FileSectionIsNotAMapping) {
  EXPECT_EQ(error_of(file("camera: 525\n"), {}), "config: camera: expected a mapping of keys");
}

TEST_F(ConfigErrors, FileRootIsNotAMapping) {
  const std::string path = file("- camera\n- lcm\n");
  EXPECT_EQ(error_of(path, {}), "config: '" + path + "': expected a mapping of keys");
}

TEST_F(ConfigErrors, FileYamlSyntaxErrorNamesTheLine) {
  const std::string path = file("camera:\n  fx: 500\n  fy: [510\n");
  EXPECT_EQ(error_of(path, {}), "config: '" + path + "' line 4: end of sequence flow not found");
}

TEST_F(ConfigErrors, FileMissing) {
  const std::string path = (dir_ / "absent.yaml").string();
  EXPECT_EQ(error_of(path, {}), "config: cannot read '" + path + "'");
}

TEST_F(ConfigErrors, FileCrossFieldPrincipalPointOutsideImage) {
  EXPECT_EQ(error_of(file("camera:\n  width: 300\n"), {}),
            "config: camera.cx: value 319.500000 lies outside the image; allowed [0, 300] "
            "(camera.width)");
}

TEST_F(ConfigErrors, SetNotAnInteger) {
  EXPECT_EQ(error_of("", {"camera.width=wide"}),
            "config: camera.width: value 'wide' is not an integer");
  EXPECT_EQ(error_of("", {"camera.width=640.5"}),
            "config: camera.width: value '640.5' is not an integer");
}

TEST_F(ConfigErrors, SetNotANumber) {
  EXPECT_EQ(error_of("", {"camera.fx=fast"}), "config: camera.fx: value 'fast' is not a number");
  EXPECT_EQ(error_of("", {"camera.fx=nan"}), "config: camera.fx: value 'nan' is not a number");
}

TEST_F(ConfigErrors, SetNotABoolean) {
  EXPECT_EQ(error_of("", {"lcm.publish_bot_core_pose=maybe"}),
            "config: lcm.publish_bot_core_pose: value 'maybe' is not a boolean; allowed true or "
            "false");
}

TEST_F(ConfigErrors, SetUnknownKey) {
  EXPECT_EQ(error_of("", {"lcm.ttl=1"}),
            "config: unknown key 'lcm.ttl'; allowed in lcm: url, pose_channel, status_channel, "
            "publish_bot_core_pose, bot_core_pose_channel, image_channel, map_channel, "
            "command_channel");
}

TEST_F(ConfigErrors, SetWithoutEquals) {
  EXPECT_EQ(error_of("", {"camera.fx"}), "config: --set 'camera.fx': expected key=value");
  EXPECT_EQ(error_of("", {"=5"}), "config: --set '=5': expected key=value");
}

TEST_F(ConfigErrors, SetEmptyKeyComponent) {
  EXPECT_EQ(error_of("", {"camera..fx=500"}),
            "config: --set 'camera..fx=500': empty key component");
}

TEST_F(ConfigErrors, SetIntoAValueThatIsNotASection) {
  EXPECT_EQ(error_of(file("log_level: info\n"), {"log_level.x=1"}),
            "config: --set 'log_level.x=1': log_level is not a section");
  // Without a file the override creates the section, and the loader rejects it as a value.
  EXPECT_EQ(error_of("", {"log_level.x=1"}),
            "config: log_level: expected a single value, not a list or mapping");
}

TEST_F(ConfigErrors, SetLogLevelNotAllowed) {
  EXPECT_EQ(error_of("", {"log_level=verbose"}),
            "config: log_level: value 'verbose' is not allowed; allowed one of: debug, info, "
            "warn, error");
}

TEST_F(ConfigErrors, SetEmptyRequiredString) {
  EXPECT_EQ(error_of("", {"source="}), "config: source: must not be empty");
  EXPECT_EQ(error_of("", {"lcm.url="}), "config: lcm.url: must not be empty");
  EXPECT_EQ(error_of("", {"lcm.status_channel="}), "config: lcm.status_channel: must not be empty");
}

TEST_F(ConfigErrors, SetCrossFieldModelMismatch) {
  EXPECT_EQ(error_of("", {"camera.k4=0.01"}),
            "config: camera.k4: only used by model pinhole-equidistant; allowed 0 for "
            "pinhole-radtan");
}

TEST_F(ConfigErrors, SetCrossFieldFallbackThresholdAboveTheMainOne) {
  EXPECT_EQ(error_of("", {"features.min_fast_threshold=20"}),
            "config: features.min_fast_threshold: 20 is above features.fast_threshold 12");
  EXPECT_EQ(error_of("", {"features.min_fast_threshold=20", "features.fast_threshold=20"}),
            "(loaded)");
}

TEST_F(ConfigErrors, SetOverridesTheFileAndIsValidatedLikeIt) {
  // The file is fine; the override breaks it, and the message is the same as from a file.
  EXPECT_EQ(error_of(file("camera:\n  fx: 500\n"), {"camera.fx=0"}),
            "config: camera.fx: value '0' is out of range; allowed [1, 100000]");
}

TEST_F(ConfigErrors, CommandLinePrintsTheMessageAndExitsWith2) {
  const std::string cmd = std::string(RDSLAM_BINARY) + " config --set camera.fx=-3 2>&1";
  FILE* f = popen(cmd.c_str(), "r");
  ASSERT_NE(f, nullptr);
  std::string out;
  char buf[512];
  while (fgets(buf, sizeof(buf), f)) out += buf;
  const int rc = pclose(f);
  ASSERT_TRUE(WIFEXITED(rc));
  EXPECT_EQ(WEXITSTATUS(rc), 2);
  EXPECT_EQ(out, "rdslam: config: camera.fx: value '-3' is out of range; allowed [1, 100000]\n");
}
