#!/usr/bin/env python3
"""Summarise a seeded replay set (tests/replay/replay_set.sh -s SEEDS OUT): per sequence the
mean and worst online ATE (% of path) over the PARSAC seeds, the mean final ATE, the latest
first pose and the fewest tracked frames; with BASE (another run of the same set), the ratio of
the means and their geometric mean per group (synthetic, dominant_object, kitti06, Blender,
all). A lever is judged on these groups, not on one sequence (docs/slam.md).

Usage: tests/replay/family_summary.py OUT_DIR [BASE_DIR]
A measurement aid, not a test: exits 2 on a missing directory, 0 otherwise.
"""
import collections
import glob
import json
import math
import os
import sys


def load(directory):
    runs = {}
    for path in glob.glob(os.path.join(directory, "*.json")):
        try:
            with open(path) as f:
                r = json.load(f)
        except (OSError, ValueError):
            continue  # a run that failed leaves no report or a partial one
        name = os.path.basename(path)[:-len(".json")]
        runs[name] = {
            "ate": r.get("ate_rmse_pct_path"),
            "final": (r.get("ate_final") or {}).get("rmse_pct_path"),
            "tracked": r.get("tracked_frames"),
            "init": r.get("initialized_frame"),
        }
    return runs


def group_of(seq):
    if seq.startswith("blender_"):
        return "blender"
    if seq.startswith("kitti06"):
        return "kitti06"
    if seq.startswith("dominant_object"):
        return "dominant"
    return "synthetic"


def mean(v):
    return sum(v) / len(v)


def main(argv):
    if len(argv) not in (2, 3) or argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if len(argv) == 2 else 2
    for d in argv[1:]:
        if not os.path.isdir(d):
            print(f"family_summary: {d}: not a directory", file=sys.stderr)
            return 2
    cur = load(argv[1])
    base = load(argv[2]) if len(argv) == 3 else {}
    by_seq = collections.defaultdict(list)
    for name in sorted(cur):
        by_seq[name.split("__p")[0]].append(name)
    ratios = collections.defaultdict(list)
    head = f"{'sequence':28s} {'runs':>4s} {'mean':>7s} {'worst':>7s} {'final':>7s} {'init':>5s} {'tracked':>7s}"
    print(head + (f" | {'base':>7s} {'worst':>7s} {'ratio':>6s}" if base else ""))
    for seq, names in by_seq.items():
        ate = [cur[n]["ate"] for n in names if cur[n]["ate"] is not None]
        if not ate:
            print(f"{seq:28s} {len(names):4d} no ATE (not initialized or failed)")
            continue
        fin = [cur[n]["final"] for n in names if cur[n]["final"] is not None]
        init = max(-1 if cur[n]["init"] is None else cur[n]["init"] for n in names)
        tracked = min(cur[n]["tracked"] or 0 for n in names)
        line = (f"{seq:28s} {len(names):4d} {mean(ate):7.3f} {max(ate):7.3f} "
                f"{mean(fin) if fin else float('nan'):7.3f} {init:5d} {tracked:7d}")
        b = [base[n]["ate"] for n in names if n in base and base[n]["ate"] is not None]
        if base and len(b) == len(ate) == len(names):
            r = mean(ate) / mean(b)
            ratios[group_of(seq)].append(r)
            ratios["all"].append(r)
            line += f" | {mean(b):7.3f} {max(b):7.3f} {r:6.3f}"
        elif base:
            line += " | (not in BASE with the same runs)"
        print(line)
    for g in ("all", "synthetic", "dominant", "kitti06", "blender"):
        if ratios[g]:
            gm = math.exp(sum(map(math.log, ratios[g])) / len(ratios[g]))
            print(f"geometric mean of ratios, {g:9s} {gm:.3f} ({len(ratios[g])} sequences)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
