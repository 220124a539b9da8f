#!/usr/bin/env bash
# ThreadSanitizer on the real SLAM pipeline (issue 25): rdslam built with -fsanitize=thread
# (all of core/, drivers/, firmware_app/; -O1 -g1, Ninja, in its own build directory), then
# short replays of synth:rearrange through the four pipeline threads with the real stages:
# tracker, mapper (keyframes, triangulation, local BA), map updating (Sec. 4, on keyframe
# candidates and frame observations), snapshot publication. Once lossless (the tracker waits
# for the mapper after keyframes, as `rdslam replay`) and once --realtime --preload --speed
# 0.1 (tracker and mapper run freely side by side, newest frame wins; frames come from memory
# as from a camera, at a tenth of the recorded rate: at full rate the instrumented tracker
# processed 3 of 90 frames). OpenCV's own thread pool is off
# (threads.opencv_threads=0) and so are CHOLMOD's OpenMP threads in the local bundle
# adjustment (OMP_NUM_THREADS=1): TBB and libgomp are not instrumented, so their
# synchronisation would be invisible to TSan (a false report in cholmod's buffers under
# libgomp was the first result). Third-party suppressions: tests/tsan/suppressions.txt. Any
# report fails (halt_on_error).
#
#   tests/tsan/slam_replay.sh [-b BUILD_DIR] [-f FRAMES] [-m lossless|realtime|both]
#
#   -b BUILD_DIR  default build-tsan-slam (configured here when it has no build.ninja)
#   -f FRAMES     frames per replay (default 90)
#   -m MODE       which replays (default both)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build=build-tsan-slam frames=90 modes="lossless realtime"
while getopts "b:f:m:h" opt; do
  case "$opt" in
    b) build=$OPTARG ;;
    f) frames=$OPTARG ;;
    m) modes=$OPTARG; [[ $modes == both ]] && modes="lossless realtime" ;;
    *) sed -n '2,21p' "$0"; exit 2 ;;
  esac
done
if [[ ! -f "$build/build.ninja" ]]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRDSLAM_TSAN=ON \
    -DRDSLAM_BUILD_TESTS=OFF -DRDSLAM_WERROR=OFF -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
    >/dev/null
fi
t0=$(date +%s)
cmake --build "$build" --parallel 2 --target rdslam
t1=$(date +%s)
echo "tsan: build $((t1 - t0)) s"
export OMP_NUM_THREADS=1
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:exitcode=66:suppressions=$PWD/tests/tsan/suppressions.txt"
for mode in $modes; do
  args=()
  [[ $mode == realtime ]] && args=(--realtime --preload --speed 0.1)
  t0=$(date +%s)
  "$build/firmware_app/rdslam" replay "synth:rearrange?frames=$frames" "${args[@]}" \
    --set threads.opencv_threads=0 --set log_level=warn >"$build/tsan_$mode.log" 2>&1 || {
    echo "tsan: $mode replay FAILED (exit $?), log $build/tsan_$mode.log:" >&2
    grep -A40 -m1 "WARNING: ThreadSanitizer" "$build/tsan_$mode.log" >&2 || tail -40 "$build/tsan_$mode.log" >&2
    exit 1
  }
  echo "tsan: $mode replay of $frames frames clean ($(( $(date +%s) - t0 )) s): $(grep -E '^  (tracked|map) ' "$build/tsan_$mode.log" | tr -s ' ' | tr '\n' ';')"
done
