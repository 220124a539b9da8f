#!/usr/bin/env bash
# Cross-builds rdslam and its tests for aarch64 (Raspberry Pi 4/5, Jetson) with Debian's
# aarch64-linux-gnu-g++ against an arm64 Debian 12 sysroot (toolchain/make-arm64-sysroot.sh)
# and runs the unit tests under qemu-aarch64 (user-mode emulation, no binfmt_misc needed).
# Installs what it needs (host build deps and test helpers through install-deps.sh, the cross
# compiler, qemu-user), so it works from a clean clone on Debian 12 as root or with sudo.
#
# usage: toolchain/cross-build-aarch64.sh [--ci] [--targets "t1 t2 ..."] [--tests REGEX]
#   (default)  build everything (library, rdslam, all tests; not benchmarks/) and run every
#              unit test (ctest -L unit) under qemu-aarch64
#   --ci       the CI subset (.ci/run): build the library, rdslam and the unit test programs
#              listed in ci_tests below, run each under qemu-aarch64
#   --targets  build only these targets, then run the unit test programs among them
#   --tests    which tests: a ctest -R regex (full build) or a --gtest_filter (--targets)
# Env: RDSLAM_SYSROOT (default build-aarch64/sysroot), RDSLAM_CROSS_BUILD (default
#      build-aarch64/build), JOBS (default 2). Integration tests are built, not run.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
sysroot="${RDSLAM_SYSROOT:-$here/build-aarch64/sysroot}"
build="${RDSLAM_CROSS_BUILD:-$here/build-aarch64/build}"
jobs="${JOBS:-2}"
targets=""
tests=""
ci=0
# The CI subset: the code where aarch64 differs from x86-64. NEON FAST-9 against cv::FAST,
# blur and resize (image_ops); ORB descriptors (features); Eigen/Ceres alignment and numerics
# (geometry, pose_solvers, initializer, parsac, map_updater); byte-level pixel formats
# (mjpeg_decoder, v4l2_yuyv, v4l2_libcamera: the Raspberry Pi camera path); lock-free
# ring, frame pool and the threaded pipeline on ARM's weaker memory model (spsc_ring,
# frame_pool, pipeline); config parsing (plain char is unsigned on aarch64: config_errors,
# which also starts the rdslam binary under qemu).
# Left to the full run: synth and tracker_alloc (minutes each under qemu), the datasets,
# recorder and the rest of the CLI tests.
ci_tests=(
  test_image_ops test_features test_geometry test_pose_solvers test_initializer test_parsac
  test_map_updater test_mjpeg_decoder test_v4l2_yuyv test_v4l2_libcamera test_spsc_ring
  test_frame_pool test_pipeline test_config_errors
)
while (($#)); do
  case "$1" in
    --ci) ci=1; shift ;;
    --targets) targets="$2"; shift 2 ;;
    --tests) tests="$2"; shift 2 ;;
    -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "cross-build-aarch64: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
if ((ci)); then
  [[ -z "$targets" && -z "$tests" ]] || {
    echo "cross-build-aarch64: --ci takes no --targets/--tests" >&2; exit 2; }
  targets="rdslam ${ci_tests[*]}"
fi

t0=$(date +%s)
step() { echo "cross-build-aarch64: $* ($(( $(date +%s) - t0 )) s)"; }

# Host side: cmake, ninja, pkg-config, lcm-gen (a host tool: it runs during the build),
# ffmpeg and the .venv test helpers, then the cross compiler and qemu-user.
"$here/toolchain/install-deps.sh"
need=()
for p in g++-aarch64-linux-gnu qemu-user debian-archive-keyring; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if ((${#need[@]})); then
  step "installing ${need[*]}"
  sudo_cmd=(); [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
    "${need[@]}" >/dev/null
fi

step "sysroot $sysroot"
"$here/toolchain/make-arm64-sysroot.sh" "$sysroot"
step "configuring $build"
# Benchmarks (timing programs) are not built: timings under emulation mean nothing. The
# libcamera: source (CSI cameras of the Raspberry Pi) is built: the sysroot has libcamera.
# A unity build (CMake joins each library's sources into a few translation units: the
# OpenCV, Eigen and Ceres templates they share are compiled once per batch; the native
# Release build keeps one unit per file, so a file that compiles only inside a batch is caught
# there).
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD=ON \
  -DCMAKE_TOOLCHAIN_FILE="$here/toolchain/aarch64-linux-gnu.cmake" -DRDSLAM_SYSROOT="$sysroot" \
  -DRDSLAM_WITH_LIBCAMERA=ON -DRDSLAM_BUILD_BENCHMARKS=OFF >/dev/null
step "building ${targets:-everything}"
# shellcheck disable=SC2086
cmake --build "$build" --parallel "$jobs" ${targets:+--target $targets}
if [[ -z "$targets" || " $targets " == *" rdslam "* ]]; then
  aarch64-linux-gnu-readelf -h "$build/firmware_app/rdslam" | grep -q 'AArch64' \
    || { echo "cross-build-aarch64: rdslam is not an aarch64 binary" >&2; exit 1; }
fi

qemu=(qemu-aarch64 -L "$sysroot")
if [[ -z "$targets" ]]; then
  step "running the unit tests under qemu-aarch64 (ctest -L unit${tests:+ -R $tests})"
  ctest --test-dir "$build" -L unit ${tests:+-R "$tests"} --output-on-failure \
    --parallel "$jobs" --timeout 600
else
  # A partial build: ctest would report the programs not built as failures, so the unit
  # test programs among the targets are run directly (each test in its own source tree's
  # working directory, as ctest does).
  run=()
  for t in $targets; do
    [[ -f "$here/tests/unit/$t.cpp" ]] && run+=("$t")
  done
  step "running ${#run[@]} unit test programs under qemu-aarch64: ${run[*]}"
  failed=()
  for t in "${run[@]}"; do
    (cd "$build/tests" && "${qemu[@]}" "./$t" --gtest_brief=1 ${tests:+--gtest_filter="$tests"}) \
      || failed+=("$t")
  done
  if ((${#failed[@]})); then
    echo "cross-build-aarch64: FAILED under qemu-aarch64: ${failed[*]}" >&2
    exit 1
  fi
fi
step "done"
