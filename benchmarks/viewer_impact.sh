#!/usr/bin/env bash
# Does a viewer change rdslam's timing or drops? (issue 26, docs/viewer.md)
# Real-time replays (--realtime --preload) of one scene publishing over LCM (--lcm), in turn:
#   none     : no subscriber
#   view     : rdslam view running, polled like the page does (state 5 Hz, image and map on change)
#   killed   : rdslam view polled, then SIGKILLed halfway through the replay
#   no-image : no subscriber, viewer.image_hz=0 and viewer.map_hz=0 (poses and status only)
# Prints per run: dropped frames, tracker p50/p99, capture-to-publish latency p50/p99.
# VIEWER_IMPACT_CASES="killed" runs only the cases named.
# Usage: benchmarks/viewer_impact.sh [-b BIN] [-s SOURCE] [-r ROUNDS] [-k SPEED] [-t KILL_S] OUT_DIR
# (-k: --speed K of the replay, default 1; -t: seconds after the start that "killed" kills the
# view, default 15: after the preload, about halfway through static_xyz at K = 1)
set -euo pipefail
bin=build/firmware_app/rdslam
src=synth:static_xyz
rounds=2
speed=1
kill_s=15
while getopts "b:s:r:k:t:" o; do
  case $o in
    b) bin=$OPTARG ;; s) src=$OPTARG ;; r) rounds=$OPTARG ;; k) speed=$OPTARG ;; t) kill_s=$OPTARG ;;
    *) echo "usage: $0 [-b BIN] [-s SOURCE] [-r ROUNDS] [-k SPEED] [-t KILL_S] OUT_DIR" >&2; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
out=${1:?OUT_DIR}
mkdir -p "$out"
url="udpm://239.255.76.67:7977?ttl=0"

poll() {  # poll the view's API like the page: state at 5 Hz, image and map each second
  local base=$1 i=0
  while :; do
    curl -s -o /dev/null "$base/api/state" || true
    if ((i % 5 == 0)); then
      curl -s -o /dev/null "$base/api/image.jpg" || true
      curl -s -o /dev/null "$base/api/map" || true
    fi
    i=$((i + 1))
    sleep 0.2
  done
}

run() {  # run NAME ROUND
  local name=$1 r=$2 view_pid="" poll_pid="" extra=()
  [[ $name == no-image ]] && extra=(--set viewer.image_hz=0 --set viewer.map_hz=0)
  if [[ $name == view || $name == killed ]]; then
    "$bin" view --listen 127.0.0.1:0 --set "lcm.url=$url" >"$out/view_$name$r.txt" 2>/dev/null &
    view_pid=$!
    for _ in $(seq 50); do grep -q http "$out/view_$name$r.txt" 2>/dev/null && break; sleep 0.1; done
    local base
    base=$(grep -o 'http://[^ ]*' "$out/view_$name$r.txt" | sed 's:/$::')
    poll "$base" & poll_pid=$!
  fi
  "$bin" replay "$src" --realtime --speed "$speed" --preload --lcm --set "lcm.url=$url" "${extra[@]}" \
    --report "$out/$name$r.json" >"$out/$name$r.txt" 2>/dev/null &
  local rp=$!
  if [[ $name == killed ]]; then
    # Records whether the replay was still running when the view died.
    ( sleep "$kill_s"; kill -KILL "$view_pid" 2>/dev/null
      if kill -0 "$rp" 2>/dev/null; then state=running; else state="already ended"; fi
      echo "killed view at +$kill_s s, replay $state" >"$out/kill_$name$r.txt" ) &
  fi
  wait $rp
  if [[ -n $poll_pid ]]; then kill "$poll_pid" 2>/dev/null || true; fi
  if [[ -n $view_pid ]]; then kill "$view_pid" 2>/dev/null || true; fi
  wait 2>/dev/null || true
  python3 - "$out/$name$r.json" "$name" "$r" "$out/kill_$name$r.txt" <<'PY'
import json, os, sys
j = json.load(open(sys.argv[1]))
note = open(sys.argv[4]).read().strip() if os.path.exists(sys.argv[4]) else ""
print(f"{sys.argv[2]:9s} round {sys.argv[3]}: frames {j['frames']}, dropped {j['dropped']['total']}, "
      f"tracker p50/p99 {j['tracker_ms']['p50']:.2f}/{j['tracker_ms']['p99']:.2f} ms, "
      f"latency p50/p99 {j['latency_ms']['p50']:.2f}/{j['latency_ms']['p99']:.2f} ms"
      + (f" ({note})" if note else ""))
PY
}

echo "# $src at speed $speed, $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq "$rounds"); do
  for name in ${VIEWER_IMPACT_CASES:-none view killed no-image}; do run "$name" "$r"; done
done
echo "# load $(cut -d' ' -f1-3 /proc/loadavg)"
