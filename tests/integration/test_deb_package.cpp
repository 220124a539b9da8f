// The Debian package (cmake/packaging.cmake): `cpack -G DEB` in this build directory builds
// it, `dpkg-deb -c` shows the files in their FHS places, its Depends come from
// dpkg-shlibdeps and name packages that exist, and it installs into (and purges from) a
// scratch root with `dpkg --root`: the postinst creates the rdslam user there and enables or
// starts nothing. The host's dpkg database and users are never touched (checked).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/run_command.h"

namespace fs = std::filesystem;
using rdslam::testing::build_dir_of;
using rdslam::testing::CommandResult;
using rdslam::testing::read_text;
using rdslam::testing::run_command;
using rdslam::testing::ScratchDir;
using rdslam::testing::shell_quote;

namespace {

const fs::path kSource = RDSLAM_SOURCE_DIR;

std::string q(const fs::path& p) {
  return shell_quote(p.string());
}

// Depends: "a (>= 1), b | c, d" -> first alternative of each: {a, b, d}.
std::vector<std::string> first_alternatives(const std::string& depends) {
  std::vector<std::string> out;
  std::stringstream ss(depends);
  for (std::string item; std::getline(ss, item, ',');) {
    item = item.substr(0, item.find('|'));
    item = item.substr(0, item.find('('));
    item.erase(0, item.find_first_not_of(" \t\n"));
    item.erase(item.find_last_not_of(" \t\n") + 1);
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

bool contains_line(const std::string& text, const std::string& line) {
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) {
    if (l == line) return true;
  }
  return false;
}

class DebPackage : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    build_ = build_dir_of(RDSLAM_BINARY);
    out_ = new ScratchDir("deb");
  }
  static void TearDownTestSuite() {
    delete out_;
    out_ = nullptr;
  }
  // Builds the .deb once per process (ctest runs each test in its own); returns its path
  // (empty on failure).
  // The .deb's layout (and its conffile, maintainer scripts) assume the /usr prefix, which
  // a fresh build directory gets by default (cmake/packaging.cmake). Older build
  // directories keep a cached /usr/local: reported as skipped with the fix, not as a pass.
  static bool usr_prefix() {
    return std::regex_search(read_text(build_ / "CMakeCache.txt"),
                             std::regex("\nCMAKE_INSTALL_PREFIX:PATH=/usr\n"));
  }
  static fs::path deb() {
    if (!deb_.empty() || built_) return deb_;
    built_ = true;
    const CommandResult r = run_command("cpack --config " + q(build_ / "CPackConfig.cmake") +
                                        " -G DEB -B " + q(out_->path() / "pkg"));
    cpack_log_ = r.output;
    if (r.exit_code != 0) return {};
    for (const auto& e : fs::directory_iterator(out_->path() / "pkg")) {
      if (e.path().extension() == ".deb") deb_ = e.path();
    }
    return deb_;
  }
  static fs::path build_;
  static ScratchDir* out_;
  static fs::path deb_;
  static bool built_;
  static std::string cpack_log_;
};
fs::path DebPackage::build_;
ScratchDir* DebPackage::out_ = nullptr;
fs::path DebPackage::deb_;
bool DebPackage::built_ = false;
std::string DebPackage::cpack_log_;

}  // namespace

TEST_F(DebPackage, BuildsWithFilesInFhsPlacesAndRealDepends) {
  ASSERT_FALSE(build_.empty()) << "no CMakeCache.txt above " << RDSLAM_BINARY;
  if (!usr_prefix()) {
    GTEST_SKIP() << "this build directory installs elsewhere than /usr; the .deb needs /usr: "
                    "reconfigure with -DCMAKE_INSTALL_PREFIX=/usr (the default of a fresh build)";
  }
  const fs::path d = deb();
  ASSERT_FALSE(d.empty()) << "cpack -G DEB failed:\n" << cpack_log_;

  const CommandResult c = run_command("dpkg-deb -c " + q(d));
  ASSERT_EQ(c.exit_code, 0) << c.output;
  // "-rwxr-xr-x root/root 150616 2026-11-23 15:21 ./usr/bin/rdslam" -> mode and path.
  std::set<std::string> files;
  std::string mode_bin;
  std::stringstream ss(c.output);
  for (std::string line; std::getline(ss, line);) {
    std::stringstream ls(line);
    std::string mode, owner, size, date, time, path;
    ls >> mode >> owner >> size >> date >> time >> path;
    EXPECT_EQ(owner, "root/root") << line;
    if (mode[0] == 'd') continue;
    files.insert(path);
    if (path == "./usr/bin/rdslam") mode_bin = mode;
  }
  std::set<std::string> expected = {
      "./usr/bin/rdslam",
      "./lib/systemd/system/rdslam.service",
      "./etc/rdslam/rdslam.yaml",
      "./usr/lib/sysusers.d/rdslam.conf",
      "./usr/share/rdslam/examples/rdslam-realtime.conf",
      "./usr/share/rdslam/python/rdslam_msgs.py",
      "./usr/share/rdslam/vocab/orb_k10l4.bin",
      "./usr/share/doc/rdslam/README.md",
      "./usr/share/doc/rdslam/deploy.md",
  };
  for (const auto& e : fs::directory_iterator(kSource / "lcmtypes")) {
    if (e.path().extension() == ".lcm") {
      expected.insert("./usr/share/rdslam/lcmtypes/" + e.path().filename().string());
    }
  }
  EXPECT_EQ(files, expected);
  EXPECT_EQ(mode_bin, "-rwxr-xr-x");

  // The installed unit is the repository's (paths already /usr/bin and /etc/rdslam).
  const CommandResult unit = run_command("dpkg-deb --fsys-tarfile " + q(d) +
                                         " | tar -xO ./lib/systemd/system/rdslam.service");
  EXPECT_EQ(unit.output, read_text(kSource / "systemd/rdslam.service"));

  // /etc/rdslam/rdslam.yaml is a conffile: local edits survive upgrades.
  const CommandResult conf = run_command("dpkg-deb -I " + q(d) + " conffiles");
  EXPECT_EQ(conf.output, "/etc/rdslam/rdslam.yaml\n");

  // Depends are computed from the binary (dpkg-shlibdeps) and name real packages.
  const CommandResult f = run_command("dpkg-deb -f " + q(d) + " Depends");
  ASSERT_EQ(f.exit_code, 0) << f.output;
  const std::vector<std::string> deps = first_alternatives(f.output);
  std::printf("Depends: %s", f.output.c_str());
  // dpkg-shlibdeps found the libraries the daemon really links: libsystemd (sd_notify),
  // LCM, OpenCV, yaml-cpp, the C and C++ runtimes.
  for (const char* lib :
       {"libc6", "libstdc++6", "libsystemd0", "liblcm1", "libopencv-core406", "libyaml-cpp0.7"}) {
    EXPECT_NE(std::find(deps.begin(), deps.end(), lib), deps.end())
        << lib << " missing from Depends: " << f.output;
  }
  // Every package named exists: this very host has each one installed (it built the binary).
  for (const auto& p : deps) {
    const CommandResult s = run_command("dpkg-query -W -f='${Status}' " + shell_quote(p));
    EXPECT_EQ(s.output, "install ok installed") << "Depends names '" << p << "'";
  }
}

TEST_F(DebPackage, InstallsIntoAScratchRootAndPurges) {
  ASSERT_FALSE(build_.empty()) << "no CMakeCache.txt above " << RDSLAM_BINARY;
  if (!usr_prefix()) {
    GTEST_SKIP() << "this build directory installs elsewhere than /usr; the .deb needs /usr: "
                    "reconfigure with -DCMAKE_INSTALL_PREFIX=/usr (the default of a fresh build)";
  }
  const fs::path d = deb();
  ASSERT_FALSE(d.empty()) << "cpack -G DEB failed:\n" << cpack_log_;
  // The host must not learn about rdslam (compared as entries, not whole files: another
  // process may install unrelated packages meanwhile).
  auto host_state = [] {
    const std::string status = read_text("/var/lib/dpkg/status");
    const std::string passwd = read_text("/etc/passwd");
    return std::string(status.find("Package: rdslam\n") != std::string::npos ? "P" : "-") +
           (std::regex_search(passwd, std::regex("(^|\n)rdslam:")) ? "U" : "-");
  };
  const std::string host_before = host_state();

  // A minimal root: an empty dpkg database, root and the video group (Debian's base-passwd
  // always has them), nothing else. Maintainer scripts run outside the root
  // (--force-script-chrootless) with DPKG_ROOT set, so they need no shell inside it; the
  // libraries the binary needs are not in the root, hence --force-depends (the Depends are
  // checked against this host in the test above).
  ScratchDir root("dpkgroot");
  const fs::path r = root.path();
  for (const char* sub : {"var/lib/dpkg/info", "var/lib/dpkg/updates", "var/log", "etc"}) {
    fs::create_directories(r / sub);
  }
  for (const char* f : {"var/lib/dpkg/status", "var/lib/dpkg/available"}) {
    std::ofstream(r / f).flush();
  }
  std::ofstream(r / "etc/passwd") << "root:x:0:0:root:/root:/bin/sh\n";
  std::ofstream(r / "etc/group") << "root:x:0:\nvideo:x:44:\n";
  const std::string dpkg = std::string("dpkg --root=") + q(r) +
                           " --log=" + q(r / "var/log/dpkg.log") + " --force-script-chrootless" +
                           (geteuid() != 0 ? " --force-not-root" : "");

  const CommandResult inst = run_command(dpkg + " --force-depends -i " + q(d));
  ASSERT_EQ(inst.exit_code, 0) << inst.output;
  const CommandResult st = run_command(dpkg + " -s rdslam");
  EXPECT_NE(st.output.find("Status: install ok installed"), std::string::npos) << st.output;
  EXPECT_NE(st.output.find(" /etc/rdslam/rdslam.yaml "), std::string::npos) << st.output;

  // The files landed, and the installed binary runs.
  EXPECT_TRUE(fs::exists(r / "lib/systemd/system/rdslam.service"));
  EXPECT_TRUE(fs::exists(r / "etc/rdslam/rdslam.yaml"));
  const CommandResult ver = run_command(q(r / "usr/bin/rdslam") + " --version");
  EXPECT_EQ(ver.exit_code, 0) << ver.output;
  EXPECT_EQ(ver.output.rfind("rdslam ", 0), 0u) << ver.output;

  // postinst created the system user the unit runs as, with its state directory as home.
  const std::string passwd = read_text(r / "etc/passwd");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(passwd, m,
                                std::regex("\nrdslam:x:([0-9]+):([0-9]+):[^:]*:"
                                           "/var/lib/rdslam:([^\n]*)\n")))
      << passwd;
  EXPECT_LT(std::stoi(m[1]), 1000) << "not a system uid";
  EXPECT_NE(m[3].str().find("nologin"), std::string::npos);
  EXPECT_TRUE(std::regex_search(read_text(r / "etc/group"), std::regex("(^|\n)rdslam:x:")));

  // ... and enabled or started nothing: no wants/ symlink anywhere under /etc/systemd.
  if (fs::exists(r / "etc/systemd")) {
    for (const auto& e : fs::recursive_directory_iterator(r / "etc/systemd")) {
      EXPECT_EQ(e.path().filename().string().find("rdslam"), std::string::npos) << e.path();
    }
  }

  // Purge removes the program, the unit and the conffile (the user stays: Debian practice).
  const CommandResult purge = run_command(dpkg + " --purge rdslam");
  ASSERT_EQ(purge.exit_code, 0) << purge.output;
  EXPECT_FALSE(fs::exists(r / "usr/bin/rdslam"));
  EXPECT_FALSE(fs::exists(r / "lib/systemd/system/rdslam.service"));
  EXPECT_FALSE(fs::exists(r / "etc/rdslam/rdslam.yaml"));
  EXPECT_FALSE(contains_line(run_command(dpkg + " -l").output, "rdslam"));

  // The host was not touched.
  EXPECT_EQ(host_state(), host_before);
}
