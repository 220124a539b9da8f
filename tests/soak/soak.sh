#!/usr/bin/env bash
# Soak test (issue 25): a looped real-time replay of synth:rearrange (the desk whose objects
# move, so map updating keeps adding and removing points) under tight map caps (12
# keyframes, 2000 points: reached in the first loops, so the caps are enforced), its RSS
# sampled every second; passes when the replay exits normally, RSS after warm-up grows by
# less than 2% and the map stays under its caps (tests/soak/soak_rss.cpp).
#
#   tests/soak/soak.sh [-b BUILD] [-s SECONDS] [-w WARMUP] OUT
#
#   -b BUILD    build directory with firmware_app/rdslam and tests/soak_rss (default build)
#   -s SECONDS  replay length (default 180, CI; the documented long run is 1800)
#   -w WARMUP   seconds before the first RSS window (default 60)
#   OUT         rss.csv, rss.png (RSS curve), map.csv, report.json, replay.log, soak.txt
set -euo pipefail
build=build seconds=180 warmup=60
while getopts "b:s:w:h" opt; do
  case "$opt" in
    b) build=$OPTARG ;;
    s) seconds=$OPTARG ;;
    w) warmup=$OPTARG ;;
    *) sed -n '2,13p' "$0"; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
[[ $# -eq 1 ]] || { sed -n '2,13p' "$0"; exit 2; }
out=$1
for f in firmware_app/rdslam tests/soak_rss; do
  [[ -x "$build/$f" ]] || { echo "soak: $build/$f missing: build it first" >&2; exit 1; }
done
exec "$build/tests/soak_rss" "$build/firmware_app/rdslam" "$out" --seconds "$seconds" \
  --warmup "$warmup"
