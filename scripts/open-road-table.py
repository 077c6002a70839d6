#!/usr/bin/env python3
"""Open-road sweep table: SUMO's drivers alone against a share driven by a law, per inflow,
as the mean over seeds ± the half-width of its 95 % interval (Student's t; standard library
only).

    python3 scripts/open-road-table.py OUT/results.csv

The sweep's axes are an inflow's `vehs_per_hour` and `sumo.inflows.0.controlled.share`.
"""
import csv
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


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "results.csv"
    rows = [r for r in csv.DictReader(open(path)) if r["status"] == "complete"]
    if not rows:
        raise SystemExit(f"{path}: no complete rows")
    inflow = next(k for k in rows[0] if k.endswith(".vehs_per_hour"))
    share = "sumo.inflows.0.controlled.share"
    by = defaultdict(list)
    for r in rows:
        by[(float(r[inflow]), float(r[share]))].append(r)
    f = lambda rs, k: [float(r[k]) for r in rs]
    shares = sorted({s for _, s in by})
    head = ["inflow [veh/h]"]
    for s in shares:
        who = "SUMO's drivers" if s == 0 else f"{s:.0%} law"
        head += [f"{who}: throughput [veh/h]", f"{who}: travel time [s]",
                 f"{who}: mean speed [m/s]", f"{who}: halting"]
    print("| " + " | ".join(head) + " |")
    print("|---|" + "---:|" * (len(head) - 1))
    for q in sorted({q for q, _ in by}):
        line = [f"{q:.0f}"]
        for s in shares:
            rs = by[(q, s)]
            line += [cell(f(rs, "all_vehicles.throughput_per_hour"), 0),
                     cell(f(rs, "all_vehicles.mean_travel_time_s"), 1),
                     cell(f(rs, "all_vehicles.mean_speed_mps"), 2),
                     cell(f(rs, "all_vehicles.halting_mean"), 2)]
        print("| " + " | ".join(line) + " |")
    n = {len(rs) for rs in by.values()}
    print(f"\n{len(rows)} runs, {sorted(n)} seeds per cell; "
          f"collisions: {sum(f(rows, 'all_vehicles.collisions')):.0f}")


if __name__ == "__main__":
    main()
