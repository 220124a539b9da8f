#!/bin/sh
# The benchmark table of docs/benchmarks.md (issue 10): `rdslam bench pipeline` for both
# feature modes on synth:static_xyz (640x480) and the KITTI excerpt (1226x370), threaded
# (tracker waits for the mapper at keyframes, as `rdslam replay`), threaded with
# --async-mapper (as a live camera) and single-thread. Prints one Markdown row per run with
# the 1-minute load average before the run (the CI machine is shared: see the doc). Peak RSS
# is shown without the preloaded frames (`preload_mb`), which the process holds only for
# the benchmark.
#
# Usage (from the repo root): benchmarks/pipeline_table.sh [RDSLAM_BINARY] [SHARED_DIR]
set -eu
B=${1:-build/firmware_app/rdslam}
SHARED=${2:-../shared}
KITTI="$SHARED/data/kitti06_excerpt"

row() {  # source label, features, mode label, extra args...
  src=$1 label=$2 feat=$3 mode=$4
  shift 4
  load=$(cut -d' ' -f1 /proc/loadavg)
  "$B" bench pipeline "$src" --json --set features.mode="$feat" "$@" 2>/dev/null |
    python3 -c '
import json, sys
j = json.load(sys.stdin)
s = j["stages"]
def st(k):
    return "%.1f / %.1f" % (s[k]["p50"], s[k]["p99"]) if k in s else "-"
lat = "%.1f / %.1f" % (j["latency_ms"]["p50"], j["latency_ms"]["p99"]) if sys.argv[3] != "single-thread" else "-"
print("| %s | %s | %s | %d | %.1f%% | %.1f | %s | %s | %s | %s | %.0f MiB | %s |" % (
    sys.argv[1], sys.argv[2], sys.argv[3], j["frames"], 100 * j["tracked_ratio"], j["fps"],
    st("tracker"), st("tracker_cpu"), st("mapper"), lat,
    j["peak_rss_mb"] - j.get("preload_mb", 0.0), sys.argv[4]))
' "$label" "$feat" "$mode" "$load"
}

echo "| source | features | mode | frames | tracked | fps | tracker | tracker CPU | mapper | latency | peak RSS - frames | load |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for feat in orb sift; do
  for s in "synth:static_xyz|synth:static_xyz 640x480" "kitti:$KITTI|kitti06_excerpt 1226x370"; do
    src=${s%%|*}
    label=${s#*|}
    row "$src" "$label" "$feat" pipeline
    row "$src" "$label" "$feat" "pipeline async" --async-mapper
    row "$src" "$label" "$feat" single-thread --single-thread
  done
done
