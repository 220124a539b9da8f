#!/usr/bin/env bash
# Live replay at K x speed (issue 23 item 7; docs/benchmarks.md "Live replay at K x speed"):
# each sequence lossless once (deterministic), then `rdslam replay --realtime --speed K
# --preload` for every K, REPEATS times, with the machine's load average before each run.
# Prints one row per run: tracked % after init, ATE % of path (online), frames processed and
# dropped, tracker p50/p99 ms, keyframes, load. A measurement, not a test: timings depend on
# the machine and on what else runs on it.
#
# Usage: benchmarks/realtime_speed.sh [-b RDSLAM] [-r REPEATS] [-k "1 2 3"] OUT_DIR [-- extra args]
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
rdslam="$repo/build/firmware_app/rdslam"
repeats=2
speeds="1 2 3"
while [[ $# -gt 0 ]]; do
  case "$1" in
    -b) rdslam="$2"; shift 2 ;;
    -r) repeats="$2"; shift 2 ;;
    -k) speeds="$2"; shift 2 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    --) shift; break ;;
    -*) echo "realtime_speed: unknown option $1" >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[[ -n "${out:-}" ]] || { echo "realtime_speed: OUT_DIR missing (-h for help)" >&2; exit 2; }
mkdir -p "$out"
sources=("walking_xyz=synth:walking_xyz" "static_halfsphere=synth:static_halfsphere")
kitti="$repo/../shared/data/kitti06_excerpt"
[[ -d "$kitti" ]] && sources=("kitti06=kitti:$kitti" "${sources[@]}")

row() {  # name mode load json
  python3 - "$@" <<'PY'
import json, sys
name, mode, load, path = sys.argv[1:5]
r = json.load(open(path))
def f(v, fmt):
    return "-" if v is None else fmt.format(v)
d = r.get("dropped") or {}
t = r.get("tracker_ms") or {}
print("{:<18} {:<10} {:>7} {:>7} {:>6} {:>7} {:>6} {:>6} {:>4} {:>5}".format(
    name, mode, f(100 * r.get("tracked_ratio_after_init", 0), "{:.1f}"),
    f(r.get("ate_rmse_pct_path"), "{:.3f}"), r.get("frames"), d.get("total"),
    f(t.get("p50"), "{:.1f}"), f(t.get("p99"), "{:.1f}"), r.get("keyframes"), load))
PY
}
load() { cut -d' ' -f1 /proc/loadavg; }

printf '%-18s %-10s %7s %7s %6s %7s %6s %6s %4s %5s\n' sequence mode "trk%" "ATE%" frames dropped \
  p50ms p99ms kfs load
for s in "${sources[@]}"; do
  name=${s%%=*} uri=${s#*=}
  l=$(load)
  "$rdslam" replay "$uri" --report "$out/$name.lossless.json" "$@" > "$out/$name.lossless.log" 2>&1
  row "$name" lossless "$l" "$out/$name.lossless.json"
  for k in $speeds; do
    for rep in $(seq 1 "$repeats"); do
      l=$(load)
      j="$out/$name.x$k.r$rep.json"
      "$rdslam" replay "$uri" --realtime --speed "$k" --preload --report "$j" "$@" \
        > "${j%.json}.log" 2>&1
      row "$name" "x$k r$rep" "$l" "$j"
    done
  done
done
