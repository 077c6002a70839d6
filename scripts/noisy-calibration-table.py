#!/usr/bin/env python3
"""Distributions of the calibration sweep of the stochastic humans (standard library only).

    python3 scripts/noisy-calibration-table.py OUT/results.csv

For each run: seeds with a jam (a vehicle below 1 m/s after all drove faster) within the
horizon, the formation time (min / median / max), the wave speed in km/h (negative =
backward; min / median / max), the largest minimum speed after the warm-up (0 = every seed
has vehicles stopping), braking events per run and collisions.
"""
import csv
import statistics
import sys
from collections import defaultdict

from safety_mark import mark


def num(x):
    return None if x in ("", "null", None) else float(x)


def spread(xs, fmt):
    if not xs:
        return "—"
    return f"{fmt(min(xs))} / {fmt(statistics.median(xs))} / {fmt(max(xs))}"


rows = list(csv.DictReader(open(sys.argv[1] if len(sys.argv) > 1 else "results.csv")))
by = defaultdict(list)
for r in rows:
    by[r["run"]].append(r)
print("| run | seeds with a jam | formation time [s] min / median / max | wave [km/h] min / median / max | max of min speed [m/s] | braking events (median) | collision steps |")
print("|---|---:|---|---|---:|---:|---:|")
for run, rs in by.items():
    jam = [num(r["congestion.jam_formed_s"]) for r in rs if num(r["congestion.jam_formed_s"]) is not None]
    wave = [3.6 * num(r["congestion.wave_speed_mps"]) for r in rs if num(r["congestion.wave_speed_mps"]) is not None]
    vmin = max(num(r["congestion.min_speed_mps"]) for r in rs)
    brakes = [num(r.get("congestion.braking_events")) for r in rs if num(r.get("congestion.braking_events")) is not None]
    coll = sum(int(num(r["safety.collision_steps"]) or 0) for r in rs)
    print(f"| {run}{mark(rs)} | {len(jam)}/{len(rs)} | {spread(jam, lambda x: f'{x:.0f}')} | "
          f"{spread(wave, lambda x: f'{x:.1f}')} | {vmin:.2f} | "
          f"{statistics.median(brakes) if brakes else '—'} | {coll} |")
