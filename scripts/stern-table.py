#!/usr/bin/env python3
"""Stern et al. (2018) metrics of a one-AV sweep as paired changes against the all-human ring.

Reads the results.csv of `syncroad sweep sweeps/stern-one-av.json` and prints, per controller,
the mean change of each metric against the all-human run of the same seed (the humans draw the
same noise streams in both, so the pairs share their randomness) with its 95 % Student-t
interval over the seeds, in percent of the all-human value; a controller with unsafe runs
is marked ⚠ UNSAFE k/n. Standard library only.

    python3 scripts/stern-table.py OUT/results.csv
"""
import csv
import math
import statistics
import sys
from collections import defaultdict

from safety_mark import mark

METRICS = [
    ("congestion.speed_std_mps", "speed std"),
    ("sumo.fuel_g_per_km", "fuel"),
    ("congestion.braking_events", "braking events"),
    ("sumo.flow_veh_per_h", "throughput"),
]

# Two-sided 95 % Student-t quantiles t_{0.975, dof}.
T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
        9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131,
        16: 2.120, 17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086, 24: 2.064, 29: 2.045,
        39: 2.023, 49: 2.010}


def t975(dof):
    keys = sorted(k for k in T975 if k <= dof)
    return T975[keys[-1]] if keys else float("nan")


def mean_ci(xs):
    m = statistics.fmean(xs)
    if len(xs) < 2:
        return m, float("nan")
    return m, t975(len(xs) - 1) * statistics.stdev(xs) / math.sqrt(len(xs))


def main(path):
    rows = [r for r in csv.DictReader(open(path)) if r["status"] == "complete"]
    by = defaultdict(dict)
    for r in rows:
        by[r["run"]][r["seed"]] = r
    base = by.pop("mixed-0", None)
    if base is None:
        sys.exit("no all-human run (mixed-0) in the table")
    print(f"all-human ring ({len(base)} seeds){mark(list(base.values()))}: "
          + ", ".join(f"{label} {statistics.fmean(float(b[k]) for b in base.values()):.3f}"
                      for k, label in METRICS))
    print("| controller | " + " | ".join(f"Δ {label} [%]" for _, label in METRICS)
          + " | min gap [m] | min time headway [s] |")
    print("|---|" + "---:|" * (len(METRICS) + 2))
    for run, seeds in sorted(by.items()):
        cells = []
        for key, _ in METRICS:
            d = [100.0 * (float(r[key]) - float(base[s][key])) / float(base[s][key])
                 for s, r in seeds.items() if s in base and float(base[s][key]) != 0.0]
            m, h = mean_ci(d)
            cells.append(f"{m:+.1f} ± {h:.1f} (n={len(d)})")
        gaps = [float(r["gap_safety.min_gap_m"]) for r in seeds.values()
                if r.get("gap_safety.min_gap_m") not in (None, "", "null")]
        cells.append(f"{min(gaps):.2f}" if gaps else "—")
        heads = [float(r["gap_safety.min_time_headway_s"]) for r in seeds.values()
                 if r.get("gap_safety.min_time_headway_s") not in (None, "", "null")]
        cells.append(f"{min(heads):.2f}" if heads else "—")
        print(f"| {run}{mark(list(seeds.values()))} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results.csv")
