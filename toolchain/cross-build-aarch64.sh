#!/usr/bin/env bash
# Cross-builds rdslam and its tests for aarch64 (Raspberry Pi 4/5, Jetson) against an arm64
# Debian 12 sysroot and runs the unit tests under qemu-aarch64.
#
# usage: toolchain/cross-build-aarch64.sh [--targets "t1 t2 ..."] [--tests REGEX]
#   --targets  build only these targets (default: everything)
#   --tests    ctest -R filter for the unit tests to run (default: all unit tests)
# Env: RDSLAM_SYSROOT (default build-aarch64/sysroot), JOBS (default 2).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
sysroot="${RDSLAM_SYSROOT:-$here/build-aarch64/sysroot}"
build="$here/build-aarch64/build"
targets=""
tests=""
while (($#)); do
  case "$1" in
    --targets) targets="$2"; shift 2 ;;
    --tests) tests="$2"; shift 2 ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) echo "cross-build-aarch64: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

need=()
command -v aarch64-linux-gnu-g++ >/dev/null || need+=(g++-aarch64-linux-gnu)
command -v qemu-aarch64 >/dev/null || need+=(qemu-user)
if ((${#need[@]})); then
  echo "cross-build-aarch64: installing ${need[*]}"
  sudo_cmd=(); [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
    "${need[@]}" >/dev/null
fi

"$here/toolchain/make-arm64-sysroot.sh" "$sysroot"
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_TOOLCHAIN_FILE="$here/toolchain/aarch64-linux-gnu.cmake" -DRDSLAM_SYSROOT="$sysroot" \
  -DRDSLAM_WITH_LIBCAMERA=OFF >/dev/null
# shellcheck disable=SC2086
cmake --build "$build" --parallel "${JOBS:-2}" ${targets:+--target $targets}
file "$build/firmware_app/rdslam" 2>/dev/null | grep -q aarch64 || [[ -n "$targets" ]] \
  || { echo "cross-build-aarch64: rdslam is not an aarch64 binary" >&2; exit 1; }
echo "cross-build-aarch64: running unit tests under qemu-aarch64"
ctest --test-dir "$build" -L unit ${tests:+-R "$tests"} --output-on-failure --parallel "${JOBS:-2}" \
  --timeout 600
