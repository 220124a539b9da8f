#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/fuzz_*.cpp) with clang and runs each for a fixed
# time on its committed seed corpus (tests/fuzz/corpus/<target>/).
#
#   tests/fuzz/run.sh [-b BUILD] [-o OUT] [-t SECONDS] [TARGET ...]
#
#   -b BUILD    the gcc build of rdslam whose static libraries the targets link (default
#               build; `cmake --build BUILD` must have built rdslam first)
#   -o OUT      where the targets, their logs and the corpus grown by the run go
#               (default build-fuzz)
#   -t SECONDS  libFuzzer's -max_total_time per target (default 10; docs/reliability.md has
#               the longer run)
#   TARGET      fuzz_config fuzz_dataset_index fuzz_trajectory fuzz_mjpeg fuzz_lcm fuzz_map
#               (default all)
#
# Only each target's parser sources are compiled with clang and instrumented
# (-fsanitize=fuzzer,address,undefined: coverage feedback and the checks cover the parser);
# what they call beyond that comes uninstrumented from BUILD's libraries. A run that finds a
# crash, a leak, a sanitizer report or an exception the parser does not document stops,
# writes the input as OUT/<target>/crash-* and this script exits 1 (turn the input into a
# regression test in tests/unit, fix, commit the input to the corpus).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."

build=build out=build-fuzz seconds=10
while getopts "b:o:t:h" opt; do
  case "$opt" in
    b) build=$OPTARG ;;
    o) out=$OPTARG ;;
    t) seconds=$OPTARG ;;
    *) sed -n '2,21p' "$0"; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
targets=("$@")
((${#targets[@]})) || targets=(fuzz_config fuzz_dataset_index fuzz_trajectory fuzz_mjpeg fuzz_lcm fuzz_map)

command -v clang++ >/dev/null || { echo "fuzz: clang++ missing (toolchain/install-deps.sh)" >&2; exit 1; }
for lib in core/librdslam_core.a drivers/librdslam_drivers.a firmware_app/librdslam_app.a; do
  [[ -f "$build/$lib" ]] || { echo "fuzz: $build/$lib missing: build rdslam first" >&2; exit 1; }
done
mkdir -p "$out/lcmtypes" "$out/bin"
# The received types' generated C++ headers (as the main build makes them).
lcm-gen -x --cpp-hpath "$out/lcmtypes" lcmtypes/bot_core_image_t.lcm \
  lcmtypes/bot_core_image_metadata_t.lcm lcmtypes/rdslam_command_t.lcm >/dev/null

cxx=(clang++ -std=c++17 -O1 -g1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
  -fno-omit-frame-pointer -Wall -Wextra -Werror -I. -I"$out/lcmtypes" -isystem /usr/include/opencv4
  -isystem /usr/include/eigen3)
# Everything the uninstrumented rest may need; --as-needed keeps what is used.
libs=(-Wl,--start-group "$build/firmware_app/librdslam_app.a" "$build/drivers/librdslam_drivers.a"
  "$build/core/librdslam_core.a" -Wl,--end-group -Wl,--as-needed
  -lopencv_calib3d -lopencv_features2d -lopencv_flann -lopencv_video -lopencv_videoio
  -lopencv_imgcodecs -lopencv_imgproc -lopencv_core -lceres -lglog -lgflags -lspqr -lcholmod
  -lamd -lcamd -lccolamd -lcolamd -lsuitesparseconfig -lcxsparse -llapack -lblas -ltbb
  -lturbojpeg -llcm -lyaml-cpp -lsystemd -lz -lpthread)
[[ -f /usr/lib/x86_64-linux-gnu/libcamera.so || -f /usr/lib/aarch64-linux-gnu/libcamera.so ]] &&
  libs+=(-lcamera -lcamera-base)

declare -A sources=(
  [fuzz_config]="firmware_app/config.cpp firmware_app/pipeline_params.cpp"
  [fuzz_dataset_index]="drivers/dataset_tum.cpp drivers/dataset_euroc.cpp drivers/dataset_kitti.cpp drivers/replay_source.cpp core/camera.cpp core/timestamp.cpp"
  [fuzz_trajectory]="core/trajectory.cpp core/trajectory_eval.cpp core/timestamp.cpp"
  [fuzz_mjpeg]="drivers/mjpeg_decoder.cpp"
  [fuzz_lcm]="drivers/lcm_image_source.cpp drivers/mjpeg_decoder.cpp firmware_app/lcm_commands.cpp"
  [fuzz_map]="core/map_io.cpp"
)

# libFuzzer's -max_len: 64 KiB, but a map seed (a short synthetic run's 3 keyframes) is 66 KB.
declare -A max_len=([fuzz_map]=131072)

# One target: compile, then fuzz; the verdict goes to OUT/<target>/verdict.
run_target() {
  local t=$1 t0 t1 runs cov
  mkdir -p "$out/$t/corpus"
  t0=$(date +%s)
  # shellcheck disable=SC2086
  if ! "${cxx[@]}" -o "$out/bin/$t" "tests/fuzz/$t.cpp" ${sources[$t]} "${libs[@]}" \
    >"$out/$t/compile.txt" 2>&1; then
    echo "fuzz: $t does not compile:" >"$out/$t/verdict"
    cat "$out/$t/compile.txt" >>"$out/$t/verdict"
    return 1
  fi
  t1=$(date +%s)
  # The committed seeds stay read-only; new inputs go to OUT/<target>/corpus.
  if ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    "$out/bin/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
      -max_len="${max_len[$t]:-65536}" \
      -print_final_stats=1 -artifact_prefix="$out/$t/" "$out/$t/corpus" "tests/fuzz/corpus/$t" \
      >"$out/$t/log.txt" 2>&1; then
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$out/$t/log.txt" | grep -o '[0-9]*$' || true)
    cov=$(grep -o 'cov: [0-9]*' "$out/$t/log.txt" | tail -1 || true)
    echo "fuzz: $t clean: ${runs:-?} inputs in ${seconds} s, $cov (compile $((t1 - t0)) s)" \
      >"$out/$t/verdict"
  else
    { echo "fuzz: $t FAILED (compile $((t1 - t0)) s); log $out/$t/log.txt:"
      grep -A30 -m1 "ERROR\|runtime error\|terminate called\|deadly signal" "$out/$t/log.txt" ||
        tail -40 "$out/$t/log.txt"; } >"$out/$t/verdict"
    return 1
  fi
}

# Two targets at a time (libFuzzer runs one thread; CI has 2 cores).
for t in "${targets[@]}"; do
  [[ -n "${sources[$t]:-}" ]] || { echo "fuzz: unknown target $t" >&2; exit 2; }
done
pids=()
for t in "${targets[@]}"; do
  while (($(jobs -rp | wc -l) >= 2)); do wait -n || true; done
  run_target "$t" &
  pids+=($!)
done
status=0
for i in "${!targets[@]}"; do
  wait "${pids[$i]}" || status=1
  cat "$out/${targets[$i]}/verdict"
done
exit $status
