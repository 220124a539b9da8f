#!/usr/bin/env bash
# The replay set (issue 21's behaviour check): every built-in synthetic scenario
# (dominant_object at seeds 1-6, walking_xyz's lens variants and the dim rooms after them) and, when ../shared
# is present, the KITTI 06 excerpt, each through `rdslam replay` (lossless, deterministic,
# default configuration). Writes OUT/<name>.tum and OUT/<name>.json and prints a table:
# tracked frames, first tracked frame, ATE % of path (online, final), keyframes and map
# points at the end. With -c REF, also
# compares every trajectory byte for byte with REF/<name>.tum and exits 1 when any differs (a
# refactoring must not change them, or the change is stated with its measured effect).
#
# A measurement, not a CI test (about 7 minutes on 2 cores at one seed).
#
# Usage: tests/replay/replay_set.sh [-b RDSLAM] [-c REF_DIR] [-j JOBS] [-B DIR] [-s SEEDS] [-t] OUT_DIR [-- extra args]
#   -t  only print the table (and compare) of the runs already in OUT_DIR
#   -B  also replay every rendered Blender sequence DIR/NAME (a TUM folder with rgb.txt, made
#       by tools/blender/render.sh; kept outside the repository) as blender_NAME
#   -s  replay every sequence once per PARSAC seed in the quoted list (e.g. -s "1 2 3"), as
#       NAME__pN with --set parsac.seed=N; tests/replay/family_summary.py OUT [BASE] then gives
#       each sequence's mean and worst over the seeds and the ratios against a BASE run
#   KITTI 06 is also replayed with --every 2 and --every 3 (kitti06_every2, kitti06_every3).
set -euo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
rdslam="$repo/build/firmware_app/rdslam"
ref=""
seeds=""
jobs=2
table_only=0
blender=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    -b) rdslam="$2"; shift 2 ;;
    -c) ref="$2"; shift 2 ;;
    -j) jobs="$2"; shift 2 ;;
    -t) table_only=1; shift ;;
    -B) blender="$2"; shift 2 ;;
    -s) seeds="$2"; shift 2 ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    --) shift; break ;;
    -*) echo "replay_set: unknown option $1" >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[[ -n "${out:-}" ]] || { echo "replay_set: OUT_DIR missing (-h for help)" >&2; exit 2; }
mkdir -p "$out"
sources=()
for s in static_xyz static_halfsphere walking_xyz walking_halfsphere rigid_object rearrange \
         flashlight sitting stationary_camera_people driving; do
  sources+=("$s=synth:$s")
done
for seed in 1 2 3 4 5 6; do  # issue 22's family: a dominant moving object, by seed
  sources+=("dominant_object_s$seed=synth:dominant_object?seed=$seed")
done
for s in walking_xyz_radtan walking_xyz_fisheye dim dim_dark; do  # issue 23: lenses, dim light
  sources+=("$s=synth:$s")
done
kitti="$repo/../shared/data/kitti06_excerpt"
if [[ -d "$kitti" ]]; then
  sources+=("kitti06=kitti:$kitti" "kitti06_every2=kitti:$kitti|--every 2"
            "kitti06_every3=kitti:$kitti|--every 3")
else
  echo "replay_set: $kitti not found: kitti06 skipped" >&2
fi
if [[ -n "$blender" ]]; then  # issue 22: the second, independent renderer
  [[ -d "$blender" ]] || { echo "replay_set: -B $blender: not a directory" >&2; exit 2; }
  for d in "$blender"/*/; do
    [[ -f "$d/rgb.txt" ]] && sources+=("blender_$(basename "$d")=tum:${d%/}")
  done
fi
if [[ -n "$seeds" ]]; then  # one run per PARSAC seed: NAME__pN
  for x in $seeds; do
    [[ "$x" =~ ^[0-9]+$ ]] || { echo "replay_set: -s: '$x' is not a seed (non-negative integer)" >&2; exit 2; }
  done
  per_seed=()
  for s in "${sources[@]}"; do
    sep="|"  # the seed joins the entry's replay arguments (run_one below splits them off)
    [[ "$s" == *"|"* ]] && sep=" "
    for x in $seeds; do per_seed+=("${s%%=*}__p$x=${s#*=}$sep--set parsac.seed=$x"); done
  done
  sources=("${per_seed[@]}")
fi
run_one() {  # name=uri[|replay args]
  local name=${1%%=*} rest=${1#*=} uri extra=()
  uri=${rest%%|*}
  # shellcheck disable=SC2206
  [[ "$rest" == *"|"* ]] && extra=(${rest#*|})
  shift
  "$rdslam" replay "$uri" "${extra[@]}" --trajectory "$out/$name.tum" --report "$out/$name.json" "$@" \
    > "$out/$name.log" 2>&1 || { echo "replay_set: $name failed (see $out/$name.log)" >&2; return 1; }
}
export -f run_one
export rdslam out
(( table_only )) || printf '%s\n' "${sources[@]}" | xargs -P "$jobs" -I{} bash -c 'run_one "$@"' _ {} "$@"
status=0
printf '%-26s %8s %5s %8s %8s %5s %7s %s\n' scene tracked init "ATE %" "final %" kfs points "${ref:+vs $ref}"
for s in "${sources[@]}"; do
  name=${s%%=*}
  line=""  # a run that failed or was not made prints dashes
  [[ -f "$out/$name.json" ]] && line=$(python3 - "$out/$name.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
def f(k, fmt):
    v = r.get(k)
    return "-" if v is None else fmt.format(v)
fin = (r.get("ate_final") or {}).get("rmse_pct_path")
print(f("tracked_frames", "{}"), f("initialized_frame", "{}"), f("ate_rmse_pct_path", "{:.3f}"),
      "-" if fin is None else "{:.3f}".format(fin), f("keyframes", "{}"), f("map_points", "{}"))
PY
)
  verdict=""
  if [[ -n "$ref" ]]; then
    if [[ ! -f "$ref/$name.tum" ]]; then verdict="no reference"
    elif cmp -s "$out/$name.tum" "$ref/$name.tum"; then verdict=identical
    else verdict=DIFFERS; status=1; fi
  fi
  # shellcheck disable=SC2086
  printf '%-26s %8s %5s %8s %8s %5s %7s %s\n' "$name" ${line:-- - - - - -} "$verdict"
done
exit $status
