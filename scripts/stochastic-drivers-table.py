#!/usr/bin/env python3
"""Which stochastic driver forms a spontaneous jam (standard library only).

    python3 scripts/stochastic-drivers-table.py OUT/results.csv
"""
import csv
import statistics
import sys
from collections import defaultdict

from safety_mark import mark


def num(x):
    return None if x in ("", "null", None) else float(x)


rows = list(csv.DictReader(open(sys.argv[1] if len(sys.argv) > 1 else "results.csv")))
by = defaultdict(list)
for r in rows:
    by[r["run"]].append(r)
print("| driver | seeds with a jam | formation [s] | min speed after 400 s [m/s] | mean speed [m/s] | wave [km/h] | collision steps |")
print("|---|---:|---|---|---:|---|---:|")
for run, rs in by.items():
    jam = [num(r["congestion.jam_formed_s"]) for r in rs if num(r["congestion.jam_formed_s"]) is not None]
    wave = [3.6 * num(r["congestion.wave_speed_mps"]) for r in rs if num(r["congestion.wave_speed_mps"]) is not None]
    vmin = [num(r["congestion.min_speed_mps"]) for r in rs]
    mean = statistics.fmean(num(r["congestion.mean_speed_mps"]) for r in rs)
    coll = sum(int(num(r["safety.collision_steps"]) or 0) for r in rs)
    print(f"| `{run}`{mark(rs)} | {len(jam)}/{len(rs)} | {f'{min(jam):.0f}–{max(jam):.0f}' if jam else '—'} | "
          f"{min(vmin):.2f}–{max(vmin):.2f} | {mean:.2f} | "
          f"{f'{min(wave):.1f} … {max(wave):.1f}' if wave else '—'} | {coll} |")
