#!/usr/bin/env bash
# ThreadSanitizer on the real SLAM pipeline (issue 25): rdslam built with -fsanitize=thread
# (all of core/, drivers/, firmware_app/; -O1 -g1, Ninja, a unity build as CI's ASan stage,
# in its own build directory), then
# short runs of synth:rearrange through the pipeline threads with the real stages: tracker,
# mapper (keyframes, triangulation, local BA), map updating (Sec. 4, on keyframe candidates
# and frame observations), snapshot publication. Modes:
#   run       (CI's) `rdslam run` lossless (pipeline.replay_speed=0: the tracker waits for
#             the mapper after keyframes, as `rdslam replay`) with a map save every 0.2 s:
#             besides the four pipeline threads, the map writer thread (encodes and writes
#             the copies the mapper hands it, firmware_app/map_writer.h), the LCM publisher
#             and the supervising thread that requests the saves;
#   lossless  `rdslam replay` (lossless);
#   realtime  `rdslam replay --realtime --preload --speed 0.1` (tracker and mapper run freely
#             side by side, newest frame wins; frames come from memory as from a camera, at a
#             tenth of the recorded rate: at full rate the instrumented tracker processed 3 of
#             90 frames).
# OpenCV's own thread pool is off (threads.opencv_threads=0) and so are CHOLMOD's OpenMP
# threads in the local bundle adjustment (OMP_NUM_THREADS=1): TBB and libgomp are not
# instrumented, so their synchronisation would be invisible to TSan (a false report in
# cholmod's buffers under libgomp was the first result). Third-party suppressions:
# tests/tsan/suppressions.txt. Any report fails (halt_on_error).
#
#   tests/tsan/slam_replay.sh [-b BUILD_DIR] [-f FRAMES] [-m MODES] [-t TARGETS]
#
#   -b BUILD_DIR  default build-tsan-slam (configured here when it has no build.ninja)
#   -f FRAMES     frames per run (default 90)
#   -m MODES      run, lossless, realtime, or a quoted list (default "lossless realtime";
#                 both = "lossless realtime"; CI: -f 50 -m run)
#   -t TARGETS    also build these test programs in the same tree and the same build call
#                 (a quoted list, e.g. "test_spsc_ring test_pipeline": the tree is then
#                 configured with the tests); the caller runs them (.ci/run's TSan stage)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build=build-tsan-slam frames=90 modes="lossless realtime" targets=""
while getopts "b:f:m:t:h" opt; do
  case "$opt" in
    b) build=$OPTARG ;;
    f) frames=$OPTARG ;;
    m) modes=$OPTARG; [[ $modes == both ]] && modes="lossless realtime" ;;
    t) targets=$OPTARG ;;
    *) sed -n '2,32p' "$0"; exit 2 ;;
  esac
done
with_tests=OFF
[[ -n "$targets" ]] && with_tests=ON
# Configured when new, and again when the test programs are wanted in a tree configured
# without them (cheap: CMake keeps the cache).
configure=0
[[ -f "$build/build.ninja" ]] || configure=1
if [[ $with_tests == ON ]] && ! grep -q "^RDSLAM_BUILD_TESTS:BOOL=ON" "$build/CMakeCache.txt" 2>/dev/null; then
  configure=1
fi
if ((configure)); then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRDSLAM_TSAN=ON \
    -DRDSLAM_BUILD_TESTS=$with_tests -DRDSLAM_WERROR=OFF -DCMAKE_UNITY_BUILD=ON \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" >/dev/null
fi
t0=$(date +%s)
# shellcheck disable=SC2086  # the target list is split on purpose
cmake --build "$build" --parallel 2 --target rdslam $targets
t1=$(date +%s)
echo "tsan: build $((t1 - t0)) s"
export OMP_NUM_THREADS=1
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:exitcode=66:suppressions=$PWD/tests/tsan/suppressions.txt"
for mode in $modes; do
  log="$build/tsan_$mode.log"
  level=warn
  case $mode in
    run)
      rm -f "$build/tsan_run.map"*
      cmd=("$build/firmware_app/rdslam" run --set "source=synth:rearrange?frames=$frames"
        --set pipeline.replay_speed=0 --set "lcm.url=udpm://239.255.76.67:$((20000 + RANDOM % 20000))?ttl=0"
        --set lcm.command_channel= --set map.save_period_s=0.2 --save-map "$build/tsan_run.map")
      level=info  # the save counts are logged
      ;;
    lossless) cmd=("$build/firmware_app/rdslam" replay "synth:rearrange?frames=$frames") ;;
    realtime)
      cmd=("$build/firmware_app/rdslam" replay "synth:rearrange?frames=$frames" --realtime
        --preload --speed 0.1)
      ;;
    *) echo "tsan: unknown mode $mode" >&2; exit 2 ;;
  esac
  TIMEFORMAT='%R %U %S'
  status=0
  { time "${cmd[@]}" --set threads.opencv_threads=0 --set log_level=$level >"$log" 2>&1 ||
    status=$?; } 2>"$build/tsan_$mode.time"
  ((status == 0)) || {
    echo "tsan: $mode FAILED (exit $status), log $log:" >&2
    grep -A40 -m1 "WARNING: ThreadSanitizer" "$log" >&2 || tail -40 "$log" >&2
    exit 1
  }
  read -r wall user sys <"$build/tsan_$mode.time"
  if [[ $mode == run ]]; then
    summary=$(grep -o 'map saves while running: .*' "$log" || true)
    [[ $summary == *" 0 failed"* && $summary != *" 0 written"* ]] || {
      echo "tsan: run mode: no map saved while running ($summary), log $log" >&2
      exit 1
    }
  else
    summary=$(grep -E '^  (tracked|map) ' "$log" | tr -s ' ' | tr '\n' ';')
  fi
  echo "tsan: $mode of $frames frames clean (wall ${wall} s, cpu user ${user} s sys ${sys} s): $summary"
done
