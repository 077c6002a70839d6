#!/usr/bin/env python3
"""Open-road sweep table: SUMO's drivers alone against a share of the inflow driven by a law,
per inflow, as the mean over seeds ± the half-width of its 95 % interval (Student's t;
standard library only).

    python3 scripts/open-road-table.py OUT/results.csv

The sweep's axes are an inflow's `vehs_per_hour` and `sumo.inflows.0.controlled` (objects
such as `{"law": "follower-stopper-25", "share": 0.1}`); a share of 0 is SUMO's drivers alone.
"""
import csv
import json
import math
import statistics
import sys
from collections import defaultdict

# Two-sided 97.5 % quantiles of Student's t by degrees of freedom.
T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
        9: 2.262, 19: 2.093}


def cell(xs, digits):
    m = statistics.fmean(xs)
    if len(xs) < 2:
        return f"{m:.{digits}f}"
    h = T975.get(len(xs) - 1, 2.0) * statistics.stdev(xs) / math.sqrt(len(xs))
    return f"{m:.{digits}f} ± {h:.{digits}f}"


def who(controlled):
    c = json.loads(controlled)
    if c.get("share", 0) == 0 and not c.get("at_s"):
        return "SUMO's drivers"
    params = ", ".join(f"{k} {v}" for k, v in (c.get("params") or {}).items())
    law = f"{c['law']} ({params})" if params else c["law"]
    return f"{c['share']:.0%} {law}".replace("%", " %", 1)


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "results.csv"
    rows = [r for r in csv.DictReader(open(path)) if r["status"] == "complete"]
    if not rows:
        raise SystemExit(f"{path}: no complete rows")
    inflow = next(k for k in rows[0] if k.endswith(".vehs_per_hour"))
    by = defaultdict(lambda: defaultdict(list))
    for r in rows:
        by[who(r["sumo.inflows.0.controlled"])][float(r[inflow])].append(r)
    f = lambda rs, k: [float(r[k]) for r in rs]
    print("| inflow [veh/h] | drivers | throughput [veh/h] | travel time [s] | mean speed [m/s] "
          "| halting | unsafe runs |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for q in sorted({q for c in by.values() for q in c}):
        for w, c in by.items():
            rs = c.get(q, [])
            if not rs:
                continue
            unsafe = sum(1 for r in rs if r.get("safe") == "false")
            print(f"| {q:.0f} | {w} | {cell(f(rs, 'all_vehicles.throughput_per_hour'), 0)} | "
                  f"{cell(f(rs, 'all_vehicles.mean_travel_time_s'), 1)} | "
                  f"{cell(f(rs, 'all_vehicles.mean_speed_mps'), 2)} | "
                  f"{cell(f(rs, 'all_vehicles.halting_mean'), 2)} | {unsafe} of {len(rs)} |")
    seeds = sorted({len(rs) for c in by.values() for rs in c.values()})
    unsafe = [r for r in rows if r.get("safe") == "false"]
    unsafe_by = defaultdict(int)
    for r in unsafe:
        unsafe_by[who(r["sumo.inflows.0.controlled"])] += 1
    print(f"\n{len(rows)} runs, {seeds} seeds per cell; collisions: "
          f"{sum(f(rows, 'all_vehicles.collisions')):.0f}; runs marked unsafe: {len(unsafe)}"
          + (f" ({', '.join(f'{k}: {v}' for k, v in unsafe_by.items())})" if unsafe else ""))


if __name__ == "__main__":
    main()
