#!/usr/bin/env bash
# Endurance measurement (issue 8): synth:rearrange looped N times (default 60 = 10 minutes of
# video at 30 fps) through the whole threaded pipeline, lossless. Prints the replay summary
# and a per-loop table (maximum map points and keyframes, points invalidated so far) and
# writes the map size over time as CSV and PNG. CI runs a 2-minute version with assertions
# (tests/integration/test_loop_replay.cpp); this script is the long measurement.
#
# Usage: tests/replay/loop_rearrange.sh [-b RDSLAM] [-n LOOPS] [-o OUT_DIR] [-- replay args]
#   RDSLAM   default: build/firmware_app/rdslam (relative to the repo root)
#   OUT_DIR  default: /tmp/rdslam_loop/run-<UTC time>
# The PNG needs matplotlib (in the .venv that toolchain/install-deps.sh makes); without it
# only the CSV and the table are written.
set -euo pipefail

repo="$(cd "$(dirname "$0")/../.." && pwd)"
rdslam="$repo/build/firmware_app/rdslam"
loops=60
out=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    -b) rdslam="$2"; shift 2 ;;
    -n) loops="$2"; shift 2 ;;
    -o) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    --) shift; break ;;
    *) echo "loop_rearrange.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[[ -x "$rdslam" ]] || { echo "loop_rearrange.sh: no rdslam binary at $rdslam" >&2; exit 2; }
out=${out:-/tmp/rdslam_loop/run-$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$out"

echo "loop_rearrange: synth:rearrange x $loops ($((loops * 300)) frames), output in $out"
start=$(date +%s)
"$rdslam" replay synth:rearrange --loop "$loops" --map-log "$out/map.csv" \
  --report "$out/report.json" "$@" 2> "$out/replay.log" | tee "$out/summary.txt"
echo "wall time: $(( $(date +%s) - start )) s, load average: $(cut -d' ' -f1-3 /proc/loadavg)"

py=python3
[[ -x "$repo/.venv/bin/python" ]] && py="$repo/.venv/bin/python"
"$py" - "$out" 300 <<'PY'
import csv, sys
out, per = sys.argv[1], int(sys.argv[2])
rows = list(csv.DictReader(open(out + "/map.csv")))
loops = (len(rows) + per - 1) // per
print("\n| loop | max map points | max keyframes | invalidated so far | tracked |")
print("|---|---|---|---|---|")
for k in range(loops):
    r = rows[k * per:(k + 1) * per]
    tr = sum(x["state"] in ("TRACKING", "RELOCALIZED") for x in r)
    print("| %d | %d | %d | %s | %d/%d |" % (k + 1, max(int(x["map_points"]) for x in r),
          max(int(x["keyframes"]) for x in r), r[-1]["invalidated_points"], tr, len(r)))
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("(no matplotlib: no PNG)")
    sys.exit(0)
t = [int(x["seq"]) / 30.0 / 60.0 for x in rows]
fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
ax[0].plot(t, [int(x["map_points"]) for x in rows], lw=1)
ax[0].set_ylabel("map points")
ax[0].set_title("synth:rearrange looped %d times: map size over time" % loops)
ax[1].plot(t, [int(x["keyframes"]) for x in rows], lw=1, color="tab:orange")
ax[1].set_ylabel("keyframes")
ax[1].set_xlabel("video time [min] (one loop = 10 s)")
for a in ax:
    a.grid(alpha=0.3)
    a.set_ylim(bottom=0)
fig.tight_layout()
fig.savefig(out + "/map_size.png", dpi=90)
print("plot: %s/map_size.png" % out)
PY
