#!/usr/bin/env bash
# Does saving the map while running stall the tracker (issue 24)? `rdslam run` replays
# synth:static_halfsphere (150 frames) paced at pipeline.replay_speed (default 0.25: 7.5 fps,
# slow enough that the tracker keeps up on a loaded 2-core machine without saves) with periodic
# saves (map.save_period_s; 0 = none) and a mapper nice value, and prints per run: saves done,
# requests coalesced, frames processed and dropped, tracker p50/p99 (the run's total stats
# line), the median time a save took on the mapper thread (the whole save before the map
# writer thread, the copy since) and on the writer thread (wall and CPU), and the 1-min load
# average before the run. A measurement, not a CI test.
#
# Usage: benchmarks/map_save_stall.sh [-b RDSLAM] [-r REPEATS] [-s SPEED] [-c CONFIGS] [OUT_DIR]
#   -c CONFIGS  "period nice" pairs separated by commas (default "0 0,0.5 0,3 0,0 10,0.5 10")
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
rdslam="$repo/build/firmware_app/rdslam"
repeats=2
speed=0.25
configs="0 0,0.5 0,3 0,0 10,0.5 10"
while getopts "b:r:s:c:h" opt; do
  case "$opt" in
    b) rdslam="$OPTARG" ;; r) repeats="$OPTARG" ;; s) speed="$OPTARG" ;; c) configs="$OPTARG" ;;
    *) sed -n '2,12p' "$0"; exit 0 ;;
  esac
done
shift $((OPTIND - 1))
out="${1:-}"
out="${out:-$(mktemp -d /tmp/map_save_stall.XXXXXX)}"
mkdir -p "$out"
IFS=, read -r -a cfgs <<<"$configs"
median() { sort -n | awk '{v[NR]=$1} END {if (NR) printf "%.1f", v[int((NR+1)/2)]; else printf "-"}'; }
printf '%-8s %-6s %-3s %6s %9s %7s %8s %16s %10s %10s %10s %6s\n' period nice rep saves \
  coalesced frames dropped "trk p50/p99 ms" "mapper ms" "writer ms" "writer cpu" load
for rep in $(seq 1 "$repeats"); do
  for cfg in "${cfgs[@]}"; do
    read -r period nice <<<"$cfg"
    load=$(cut -d' ' -f1 /proc/loadavg)
    log="$out/p${period}_n${nice}_r${rep}.log"
    "$rdslam" run --set 'source=synth:static_halfsphere?frames=150' \
      --set pipeline.replay_speed="$speed" --set 'lcm.url=udpm://239.255.76.67:7739?ttl=0' \
      --set lcm.command_channel= --set map.save_period_s="$period" \
      --set threads.mapper_nice="$nice" --save-map "$out/stall.map" >"$log" 2>&1
    saves=$(grep -c 'mapper: map saved' "$log" || true)
    coalesced=$(grep -o 'saves while running: .* coalesced' "$log" | grep -o '[0-9]* coalesced' |
      cut -d' ' -f1 || true)
    frames=$(grep -o 'end of stream after [0-9]* frames' "$log" | grep -o '[0-9]*' || echo -)
    dropped=$(grep -o '([0-9]* dropped)' "$log" | grep -o '[0-9]*' || echo -)
    trk=$(grep 'stats (total)' "$log" | grep -o 'tracker p50/p99 [0-9./]*' | cut -d' ' -f3 || echo -)
    # Before the writer thread: "(..., N ms)"; with it: "copy X ms on the mapper thread,
    # encode and write Y ms on the map writer thread".
    mapper_ms=$( (grep 'mapper: map saved' "$log" | grep -o 'copy [0-9.]* ms' | cut -d' ' -f2
      grep 'mapper: map saved' "$log" | grep -v 'copy ' | grep -o ' [0-9.]* ms)' |
        grep -o '[0-9.]*') | median || true)
    writer_ms=$( (grep 'mapper: map saved' "$log" | grep -o 'write [0-9.]* ms' | cut -d' ' -f2) |
      median || true)
    writer_cpu=$( (grep 'mapper: map saved' "$log" | grep -o '([0-9.]* ms CPU)' | grep -o '[0-9.]*') |
      median || true)
    printf '%-8s %-6s %-3s %6s %9s %7s %8s %16s %10s %10s %10s %6s\n' "$period" "$nice" "$rep" \
      "$saves" "${coalesced:--}" "$frames" "$dropped" "$trk" "$mapper_ms" "$writer_ms" \
      "$writer_cpu" "$load"
  done
done
