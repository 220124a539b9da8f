#!/usr/bin/env bash
# Real-time replay measurement (issue 10): 2 minutes of 640x480 at 30 fps through the full
# threaded pipeline (`rdslam replay --realtime`), default ORB mode. Prints the replay summary,
# the pipeline's final stats line (every kind of drop), the machine load, and writes a
# capture-to-publish latency histogram (PNG, plus a text histogram on stdout).
#
# A measurement, not a pass/fail test (timings are never asserted; docs/benchmarks.md).
#
# The sequence is pre-rendered once (`rdslam synth SCENARIO --frames 3600 --out DIR`, TUM
# folder, about 2.5 GB, 15-40 min on a loaded 2-core machine) and reused, so the renderer's
# cost (20-40 ms per frame) is not in the real-time run; the capture thread still decodes one
# PNG per frame (as a webcam's MJPEG frames are decoded), which is part of the pipeline.
#
# Usage: tests/replay/realtime_2min.sh [-b RDSLAM] [-s SEQ_DIR] [-o OUT_DIR] [-n SCENARIO] [-c]
#                                      [-- extra rdslam replay args, e.g. --set threads.x=y]
#   -c       cold cache: drop the sequence's frames from the page cache first (worst case)
#   RDSLAM   default: build/firmware_app/rdslam (relative to the repo root)
#   SEQ_DIR  default: /tmp/rdslam_rt2min/<scenario>_3600 (rendered when missing)
#   OUT_DIR  default: /tmp/rdslam_rt2min/run-<UTC time>
set -euo pipefail

repo="$(cd "$(dirname "$0")/../.." && pwd)"
rdslam="$repo/build/firmware_app/rdslam"
scenario=static_xyz
seq=""
cold=0
out=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    -b) rdslam="$2"; shift 2 ;;
    -s) seq="$2"; shift 2 ;;
    -o) out="$2"; shift 2 ;;
    -n) scenario="$2"; shift 2 ;;
    -c) cold=1; shift ;;
    --) shift; break ;;
    -h|--help) awk 'NR > 1 && /^#/ { print } /^set /{ exit }' "$0"; exit 0 ;;
    *) echo "unknown argument: $1 (see --help)" >&2; exit 2 ;;
  esac
done
frames=3600  # 2 minutes at the synthetic camera's 30 fps
seq="${seq:-/tmp/rdslam_rt2min/${scenario}_${frames}}"
out="${out:-/tmp/rdslam_rt2min/run-$(date -u +%Y%m%dT%H%M%S)}"
[[ -x "$rdslam" ]] || { echo "no rdslam binary at $rdslam (build it, or pass -b)" >&2; exit 2; }

if [[ ! -f "$seq/rgb.txt" || $(grep -vc '^#' "$seq/rgb.txt") -ne $frames ]]; then
  if [[ -e "$seq" ]]; then
    echo "$seq exists but is not a complete $frames-frame sequence; remove it first" >&2
    exit 2
  fi
  echo "rendering $frames frames of $scenario into $seq (once)..."
  mkdir -p "$(dirname "$seq")"
  "$rdslam" synth "$scenario" --frames "$frames" --out "$seq" 2>&1 | tr '\r' '\n' | tail -1
fi

mkdir -p "$out"
if [[ $cold -eq 1 ]]; then
  python3 - "$seq/rgb" <<'PY'
import glob, os, sys
for path in glob.glob(os.path.join(sys.argv[1], "*")):
    fd = os.open(path, os.O_RDONLY)
    os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    os.close(fd)
PY
  echo "page cache: frames of $seq dropped"
fi
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg) on $(nproc) cores"
"$rdslam" replay "tum:$seq" --realtime --report "$out/report.json" \
  --timings "$out/frames.csv" "$@" >"$out/summary.txt" 2>"$out/log.txt"
echo "load after:  $(cut -d' ' -f1-3 /proc/loadavg)"
cat "$out/summary.txt"
grep -E 'pipeline threads|stats \(total\)' "$out/log.txt" | sed 's/^/  /'

# Histogram of capture-to-publish latency (ms), text and PNG.
py="$repo/.venv/bin/python"
[[ -x "$py" ]] || py=python3
"$py" - "$out/frames.csv" "$out/latency_hist.png" <<'PY'
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
lat = sorted(float(r["latency_ms"]) for r in rows)
if not lat:
    sys.exit("no frames")
def pct(q):
    i = q * (len(lat) - 1)
    lo = math.floor(i)
    hi = min(lo + 1, len(lat) - 1)
    return lat[lo] + (lat[hi] - lat[lo]) * (i - lo)
print(f"latency ms over {len(lat)} published frames: p50 {pct(.5):.2f} p90 {pct(.9):.2f} "
      f"p99 {pct(.99):.2f} p99.9 {pct(.999):.2f} max {lat[-1]:.2f}; "
      f"> 40 ms: {sum(x > 40 for x in lat)}")
edges = [0, 5, 10, 15, 20, 25, 30, 40, 50, 75, 100, 200, 500, float("inf")]
for a, b in zip(edges, edges[1:]):
    n = sum(a <= x < b for x in lat)
    label = f"{a:>4g}-{b:<4g}" if b != float("inf") else f"{a:>4g}+    "
    print(f"  {label} ms {n:6d} {'#' * (0 if n == 0 else max(1, round(60 * n / len(lat))))}")
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib not available: no PNG")
    sys.exit(0)
fig, ax = plt.subplots(figsize=(8, 4.5))
top = max(60.0, min(lat[-1] * 1.05, 1000.0))
ax.hist(lat, bins=120, range=(0, top), color="tab:blue")
ax.set_yscale("log")
for q, c in ((.5, "green"), (.99, "red")):
    ax.axvline(pct(q), color=c, linestyle="--", label=f"p{int(q * 100)} {pct(q):.1f} ms")
ax.axvline(40, color="black", linestyle=":", label="40 ms (issue 10)")
ax.set_xlabel("capture-to-publish latency (ms)")
ax.set_ylabel("frames")
ax.set_title(f"rdslam replay --realtime, {len(lat)} frames")
ax.legend()
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=100)
print(f"histogram: {sys.argv[2]}")
PY
echo "outputs: $out (summary.txt, log.txt, report.json, frames.csv, latency_hist.png)"
