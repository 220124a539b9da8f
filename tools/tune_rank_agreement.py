#!/usr/bin/env python3
"""Rank agreement of `rdslam tune`'s objectives (docs/tune.md, "Rank agreement").

For each `rdslam tune` output directory given, reads results.jsonl and each run's online
trajectory (runs/KEY/online.tum), scores every configuration with the ate objective and the
consistency objective (the formulas of firmware_app/tune.cpp: consistency_pct + roughness_pct,
the tracking penalty and the failure score; roughness recomputed from online.tum, so that
results.jsonl files written before roughness_pct existed can be scored), and prints Spearman,
Kendall tau-b and whether the consistency objective's best is the ate best or within 10% of it.

Usage: tools/tune_rank_agreement.py DIR [DIR ...]
"""
import json
import math
import os
import sys

FAILURE, MIN_TRACKED, WEIGHT = 100.0, 0.95, 0.1


def positions(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            out.append(v[1:4])
    return out


def roughness_pct(p):
    if len(p) < 3:
        return None
    dist = lambda a, b: math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))
    path = sum(dist(p[i], p[i - 1]) for i in range(1, len(p)))
    if path <= 0:
        return None
    sq = [sum((p[i + 1][k] - 2 * p[i][k] + p[i - 1][k]) ** 2 for k in range(3))
          for i in range(1, len(p) - 1)]
    return 100.0 * math.sqrt(sum(sq) / len(sq)) / path


def score(r, e):
    if not r["ok"] or not r["initialized"] or e is None:
        return FAILURE
    return min(FAILURE, e + WEIGHT * 100.0 * max(0.0, MIN_TRACKED - r["tracked_ratio_after_init"]))


def ranks(v):
    order = sorted(range(len(v)), key=lambda i: v[i])
    r = [0.0] * len(v)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and v[order[j + 1]] == v[order[i]]:
            j += 1
        for k in range(i, j + 1):
            r[order[k]] = (i + j) / 2.0 + 1
        i = j + 1
    return r


def spearman(a, b):
    ra, rb = ranks(a), ranks(b)
    ma, mb = sum(ra) / len(ra), sum(rb) / len(rb)
    sab = sum((x - ma) * (y - mb) for x, y in zip(ra, rb))
    saa = sum((x - ma) ** 2 for x in ra)
    sbb = sum((y - mb) ** 2 for y in rb)
    return sab / math.sqrt(saa * sbb) if saa > 0 and sbb > 0 else 0.0


def kendall(a, b):
    c = d = ta = tb = 0
    for i in range(len(a)):
        for j in range(i + 1, len(a)):
            da, db = a[i] - a[j], b[i] - b[j]
            if da == 0 and db == 0:
                continue
            if da == 0:
                ta += 1
            elif db == 0:
                tb += 1
            elif (da > 0) == (db > 0):
                c += 1
            else:
                d += 1
    den = math.sqrt((c + d + ta) * (c + d + tb))
    return (c - d) / den if den else 0.0


for d in sys.argv[1:]:
    ate, cons = [], []
    with open(os.path.join(d, "results.jsonl")) as f:
        for line in f:
            r = json.loads(line)
            online = os.path.join(d, "runs", r["key"], "online.tum")
            rough = roughness_pct(positions(online)) if os.path.exists(online) else None
            c = None
            if r["consistency_pct"] is not None and rough is not None:
                c = r["consistency_pct"] + rough
            ate.append(score(r, r["ate_pct"]))
            cons.append(score(r, c))
    best_a = min(range(len(ate)), key=lambda i: ate[i])
    best_c = min(range(len(cons)), key=lambda i: cons[i])
    within = ate[best_c] <= 1.1 * ate[best_a]
    tau = kendall(ate, cons)
    print("%-32s n %d  ate %.2f-%.2f  Spearman %.2f  Kendall %.2f  same best %s  "
          "consistency best's ate %.3f (best %.3f, within 10%% %s)  same order %s"
          % (os.path.basename(d.rstrip("/")), len(ate), min(ate), max(ate), spearman(ate, cons),
             tau, "yes" if best_a == best_c else "no", ate[best_c], ate[best_a],
             "yes" if within else "no", "yes" if within and tau > 0.6 else "no"))
