#!/usr/bin/env bash
# Issue 8's results table: the dynamic synthetic scenarios x the paper's ablations, each a
# lossless threaded `rdslam replay` (deterministic), printed as a Markdown table (ATE Sim3,
# % of path, tracked % after initialization, first tracked frame, map size, points
# invalidated). Precision/recall of map updating need the renderer's ground truth per point:
# they come from tests/integration/test_dynamic_rearrange.cpp, not from this script.
#
# Usage (from the repo root): benchmarks/dynamic_table.sh [RDSLAM] [-- extra replay args]
set -euo pipefail
B=${1:-build/firmware_app/rdslam}
[[ $# -gt 0 ]] && shift
[[ ${1:-} == "--" ]] && shift
extra=("$@")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

run() {  # id scenario ablation-label args...
  local id=$1 sc=$2 label=$3
  shift 3
  "$B" replay "synth:$sc" --report "$tmp/$id.json" "$@" "${extra[@]}" >/dev/null 2>&1 || true
  python3 - "$tmp/$id.json" "$sc" "$label" > "$tmp/$id.row" <<'PY'
import json, sys
try:
    j = json.load(open(sys.argv[1]))
except Exception:
    print("| %s | %s | failed | | | | | |" % (sys.argv[2], sys.argv[3])); sys.exit(0)
ate = j.get("ate_rmse_m"); pct = j.get("ate_rmse_pct_path")
print("| %s | %s | %s | %s | %.1f%% | %d | %d / %d | %d |" % (
    sys.argv[2], sys.argv[3], "%.4f" % ate if ate is not None else "-",
    "%.3f%%" % pct if pct is not None else "-", 100 * j["tracked_ratio_after_init"],
    j["initialized_frame"], j["map_points"], j["keyframes"], j.get("invalidated_points", -1)))
PY
}

jobs_list=()
i=0
for sc in rigid_object walking_xyz walking_halfsphere rearrange flashlight sitting; do
  jobs_list+=("$((i++)) $sc full")
  jobs_list+=("$((i++)) $sc no-map-update --no-map-update")
  jobs_list+=("$((i++)) $sc no-occlusion-handling --no-occlusion-handling")
  jobs_list+=("$((i++)) $sc ransac --estimator ransac")
done
for j in "${jobs_list[@]}"; do
  while (( $(jobs -rp | wc -l) >= 2 )); do wait -n; done
  # shellcheck disable=SC2086
  run $j &
done
wait
echo "| scenario | ablation | ATE (m) | % of path | tracked after init | first tracked | map points / keyframes | invalidated |"
echo "|---|---|---|---|---|---|---|---|"
for ((k = 0; k < i; ++k)); do cat "$tmp/$k.row"; done
