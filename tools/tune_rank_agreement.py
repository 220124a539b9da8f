#!/usr/bin/env python3
"""Rank agreement of `rdslam tune`'s objectives (docs/tune.md, "Rank agreement").

For each `rdslam tune` output directory given, reads results.jsonl and each run's online
trajectory (runs/KEY/online.tum), scores every configuration with the ate objective and the
consistency objective (the formulas of firmware_app/tune.cpp: consistency_pct + roughness_pct
+ disagreement, the tracking penalty and the failure score; roughness recomputed from
online.tum, so that results.jsonl files written before roughness_pct existed can be scored;
disagreement = median Sim(3)-aligned distance to the other configurations that track at least
95% after initialization, as tune_disagreement_pct), and prints Spearman, Kendall tau-b and
whether the consistency objective's best is the ate best or within 10% of it, for the
objective with and without the disagreement term. Assumes one sequence per directory (the
rank studies of docs/tune.md). Needs numpy (the .venv of toolchain/install-deps.sh).

Usage: tools/tune_rank_agreement.py DIR [DIR ...]
"""
import json
import math
import os
import sys

try:
    import numpy as np
except ImportError:
    sys.exit("tune_rank_agreement.py needs numpy: run it with .venv/bin/python "
             "(toolchain/install-deps.sh)")

FAILURE, MIN_TRACKED, WEIGHT = 100.0, 0.95, 0.1


def stamped(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            out.append((round(v[0] * 1e9), v[1:4]))
    return out


def aligned_rms_pct(gt, est):
    """Sim(3) (Umeyama) alignment of est onto gt on common stamps; RMS in % of gt's path."""
    g, e = dict(gt), dict(est)
    ts = sorted(set(g) & set(e))
    if len(ts) < 3:
        return None
    A, B = np.array([e[t] for t in ts]), np.array([g[t] for t in ts])
    ma, mb = A.mean(0), B.mean(0)
    xa, xb = A - ma, B - mb
    U, S, Vt = np.linalg.svd(xb.T @ xa / len(ts))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1
    var = (xa ** 2).sum() / len(ts)
    path = np.linalg.norm(np.diff(B, axis=0), axis=1).sum()
    if var <= 0 or path <= 0:
        return None
    R, s = U @ D @ Vt, np.trace(np.diag(S) @ D) / var
    res = B - (s * (R @ A.T).T + (mb - s * R @ ma))
    return 100.0 * math.sqrt((res ** 2).sum(1).mean()) / path


def disagreement(trajs, peer):
    out = [None] * len(trajs)
    for i, a in enumerate(trajs):
        if a is None or len(a) < 3:
            continue
        ds = []
        for j, b in enumerate(trajs):
            if j == i or not peer[j] or b is None or len(b) < 3:
                continue
            x, y = aligned_rms_pct(a, b), aligned_rms_pct(b, a)
            if x is not None and y is not None:
                ds.append(0.5 * (x + y))
        out[i] = float(np.median(ds)) if ds else 0.0
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
    rows = []
    with open(os.path.join(d, "results.jsonl")) as f:
        rows = [json.loads(line) for line in f if line.strip()]
    trajs, rough = [], []
    for r in rows:
        online = os.path.join(d, "runs", r["key"], "online.tum")
        t = stamped(online) if os.path.exists(online) and r["ok"] and r["initialized"] else None
        trajs.append(t)
        rough.append(roughness_pct([p for _, p in t]) if t else None)
    peer = [t is not None and r["tracked_ratio_after_init"] >= MIN_TRACKED
            for r, t in zip(rows, trajs)]
    x = disagreement(trajs, peer)
    ate = [score(r, r["ate_pct"]) for r in rows]
    line = "%-28s n %d  ate %.2f-%.2f" % (os.path.basename(d.rstrip("/")), len(ate), min(ate),
                                         max(ate))
    for label, with_x in (("C+R", False), ("C+R+X", True)):
        cons = []
        for r, ro, xi in zip(rows, rough, x):
            c = None
            if r["consistency_pct"] is not None and ro is not None:
                c = r["consistency_pct"] + ro + ((xi or 0.0) if with_x else 0.0)
            cons.append(score(r, c))
        best_a = min(range(len(ate)), key=lambda i: ate[i])
        best_c = min(range(len(cons)), key=lambda i: cons[i])
        within = ate[best_c] <= 1.1 * ate[best_a]
        tau = kendall(ate, cons)
        line += ("  | %s: Spearman %.2f Kendall %.2f, best's ate %.3f (ate best %.3f), same "
                 "order %s" % (label, spearman(ate, cons), tau, ate[best_c], ate[best_a],
                               "yes" if within and tau > 0.6 else "no"))
    print(line)
