#!/usr/bin/env python3
"""Penetration sweep table: mean ± 95 % half-width over seeds (standard library only).

    python3 scripts/penetration-table.py OUT/results.csv
"""
import csv
import math
import statistics
import sys
from collections import defaultdict

from safety_mark import mark

T975 = {9: 2.262, 19: 2.093}


def ci(xs):
    m = statistics.fmean(xs)
    h = T975.get(len(xs) - 1, 2.0) * statistics.stdev(xs) / math.sqrt(len(xs)) if len(xs) > 1 else float("nan")
    return m, h


def cell(xs, digits):
    m, h = ci(xs)
    return f"{m:.{digits}f} ± {h:.{digits}f}"


rows = [r for r in csv.DictReader(open(sys.argv[1] if len(sys.argv) > 1 else "results.csv")) if r["status"] == "complete"]
by = defaultdict(list)
for r in rows:
    ctl = "all" if r["run"] == "mixed-0" else r["run"].rsplit("-mixed-", 1)[0]
    by[(float(r["penetration"]), ctl)].append(r)
pens = sorted({p for p, _ in by})
ctls = ["protocol", "follower-stopper-4.3", "pi-saturation"]
f = lambda rs, k: [float(r[k]) for r in rs]
print("| penetration (of 22) | law: speed std [m/s] | law: collision steps | FollowerStopper: speed std | PI: speed std | law: fuel [g/km] | FollowerStopper: fuel | PI: fuel | min gap, law / FS / PI [m] | unsafe runs, law / FS / PI |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
for p in pens:
    get = (lambda c: by[(p, "all")]) if p == 0 else (lambda c: by[(p, c)])
    law, fs, pi = (get(c) for c in ctls)
    k = round(p * 22)
    print(f"| {p:.2g} ({k}) | {cell(f(law, 'congestion.speed_std_mps'), 3)} | "
          f"{statistics.fmean(f(law, 'safety.collision_steps')):.0f} | "
          f"{cell(f(fs, 'congestion.speed_std_mps'), 3)} | {cell(f(pi, 'congestion.speed_std_mps'), 3)} | "
          f"{cell(f(law, 'sumo.fuel_g_per_km'), 1)} | {cell(f(fs, 'sumo.fuel_g_per_km'), 1)} | "
          f"{cell(f(pi, 'sumo.fuel_g_per_km'), 1)} | "
          f"{min(f(law, 'gap_safety.min_gap_m')):.2f} / {min(f(fs, 'gap_safety.min_gap_m')):.2f} / {min(f(pi, 'gap_safety.min_gap_m')):.2f} | "
          f"{mark(law) or 'none'} / {mark(fs) or 'none'} / {mark(pi) or 'none'} |")
