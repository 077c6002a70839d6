#!/usr/bin/env python3
"""Calibrate a "human" SUMO driver on the Sugiyama ring: does a stop-and-go jam form by itself?

Runs N vehicles (default 22) on sumo-nets/sugiyama-ring.net.xml (230.3592 m in SUMO) from a
near-uniform start (even spacing, equal speeds, a tiny seeded jitter of the positions), with a
0.1 s step, the ballistic update and no jam teleports, and measures per seed:

* the time the first vehicle falls below 1 m/s (formation time);
* the minimum speed after the warm-up;
* the backward speed of the jam, two ways:
  1. tracking: the ring position of the slowest vehicle, sampled every second after the
     warm-up, unwrapped and fitted with a least-squares line (slope in m/s);
  2. encounter period: a vehicle meets the jam once per period P, so the jam moves at
     c = L/P - v_mean relative to the road (Sugiyama et al. 2008 measured ~20 km/h).

Usage (from the repository root, with the project's virtualenv):
    .venv/bin/python python-host/calibrate_human.py --seeds 1 2 3 \
        --vtype 'carFollowModel="IDM" accel="1.0" decel="1.5" tau="1.0" minGap="2.0" delta="4"'

Prints one line per seed and a JSON summary. Pure standard library + libsumo.
"""
import argparse
import json
import math
import os
import random
import sys
import tempfile

import libsumo as ls

HERE = os.path.dirname(os.path.abspath(__file__))
NET = os.path.join(HERE, "..", "sumo-nets", "sugiyama-ring.net.xml")
EDGES = ["arc0", "arc1", "arc2", "arc3"]


def ring_layout():
    """Start offset of each normal edge in ring coordinates and the ring length (normal +
    internal lanes, as SUMO reports them)."""
    starts, s = {}, 0.0
    lengths = {}
    for e in EDGES:
        starts[e] = s
        lengths[e] = ls.lane.getLength(e + "_0")
        s += lengths[e]
        # the internal lane at the junction after edge e
        s += ls.lane.getLength(":n%d_0_0" % ((EDGES.index(e) + 1) % 4))
    return starts, lengths, s


def write_routes(path, vtype_attrs, n, ring_len, lengths, starts, depart_speed, jitter_m, rng):
    lines = ['<routes>', '  <vType id="human" %s/>' % vtype_attrs]
    for k in range(4):
        edges = " ".join(EDGES[k:] + EDGES[:k])
        lines.append('  <route id="r%d" edges="%s" repeat="2000"/>' % (k, edges))
    spacing = ring_len / n
    for i in range(n):
        s = i * spacing + rng.uniform(-jitter_m, jitter_m)
        s %= ring_len
        edge = max((e for e in EDGES if starts[e] <= s), key=lambda e: starts[e])
        pos = s - starts[edge]
        if pos > lengths[edge] - 0.01:  # inside the 0.1 m internal lane: move onto the next edge
            edge = EDGES[(EDGES.index(edge) + 1) % 4]
            pos = 0.0
        lines.append(
            '  <vehicle id="v%02d" type="human" route="r%d" depart="0" departLane="0" '
            'departPos="%.4f" departSpeed="%.3f"/>' % (i, EDGES.index(edge), pos, depart_speed))
    lines.append('</routes>')
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def lsq_slope(ts, ys):
    n = len(ts)
    mt, my = sum(ts) / n, sum(ys) / n
    sxx = sum((t - mt) ** 2 for t in ts)
    sxy = sum((t - mt) * (y - my) for t, y in zip(ts, ys))
    slope = sxy / sxx
    resid = [y - (my + slope * (t - mt)) for t, y in zip(ts, ys)]
    rms = math.sqrt(sum(r * r for r in resid) / n)
    return slope, rms


def run(args, seed):
    """One seed's run, its routes and SUMO's log in a temporary folder removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="calib-") as tmp:
        return run_in(args, seed, tmp)


def run_in(args, seed, tmp):
    rng = random.Random(seed)
    rou = os.path.join(tmp, "ring.rou.xml")
    # First start with no vehicles to read the lane lengths.
    ls.start(["sumo", "-n", NET, "--no-step-log", "true", "--no-warnings", "true"])
    starts, lengths, ring_len = ring_layout()
    ls.close()
    write_routes(rou, args.vtype, args.n, ring_len, lengths, starts, args.depart_speed,
                 args.jitter, rng)
    ls.start(["sumo", "-n", NET, "-r", rou, "--step-length", str(args.step),
              "--step-method.ballistic", "true", "--time-to-teleport", "-1",
              "--seed", str(seed), "--no-step-log", "true", "--collision.action", "warn",
              "--log", os.path.join(tmp, "sumo.log")])
    ls.simulationStep()
    ids = sorted(ls.vehicle.getIDList())
    if len(ids) != args.n or ls.simulation.getMinExpectedNumber() != args.n:
        raise SystemExit("seed %d: only %d of %d vehicles on the road" % (seed, len(ids), args.n))
    start_pos = {}
    for v in ids:
        e = ls.vehicle.getRoadID(v)
        start_pos[v] = starts[e] + ls.vehicle.getLanePosition(v)
    steps = int(round(args.horizon / args.step))
    sample_every = int(round(1.0 / args.step))
    t_form = None
    v_min_after = float("inf")
    track_t, track_x = [], []
    speed_series = {v: [] for v in ids}
    collisions = 0
    prev_x = None
    for k in range(1, steps + 1):
        ls.simulationStep()
        collisions += ls.simulation.getCollidingVehiclesNumber()
        t = ls.simulation.getTime()
        speeds = {v: ls.vehicle.getSpeed(v) for v in ids}
        vmin = min(speeds.values())
        if t_form is None and vmin < 1.0 and t > 5.0:
            t_form = t
        if t >= args.warmup:
            v_min_after = min(v_min_after, vmin)
        if k % sample_every == 0 and t >= args.warmup:
            x = {v: (start_pos[v] + ls.vehicle.getDistance(v)) % ring_len for v in ids}
            slow = min(ids, key=lambda v: speeds[v])
            xs = x[slow]
            if prev_x is not None:
                d = xs - (prev_x % ring_len)
                d = (d + ring_len / 2) % ring_len - ring_len / 2
                xs_unwrapped = prev_x + d
            else:
                xs_unwrapped = xs
            prev_x = xs_unwrapped
            track_t.append(t)
            track_x.append(xs_unwrapped)
            for v in ids:
                speed_series[v].append(speeds[v])
    mean_speed = sum(sum(s) for s in speed_series.values()) / sum(len(s) for s in speed_series.values())
    ls.close()
    slope, rms = lsq_slope(track_t, track_x) if len(track_t) > 2 else (float("nan"), float("nan"))
    # Encounter period: downward crossings of the mean speed, per vehicle.
    periods = []
    for v, s in speed_series.items():
        thr = mean_speed
        downs = [i for i in range(1, len(s)) if s[i - 1] >= thr > s[i]]
        # ignore chatter: keep crossings at least 5 s apart
        kept = []
        for i in downs:
            if not kept or i - kept[-1] >= 5:
                kept.append(i)
        if len(kept) >= 2:
            periods.append((kept[-1] - kept[0]) / (len(kept) - 1))  # samples are 1 s apart
    period = sum(periods) / len(periods) if periods else float("nan")
    c_period = ring_len / period - mean_speed if periods else float("nan")
    return {
        "seed": seed,
        "ring_m": ring_len,
        "t_first_below_1mps_s": t_form,
        "min_speed_after_warmup_mps": v_min_after,
        "mean_speed_mps": mean_speed,
        "wave_track_mps": slope,
        "wave_track_kmh": slope * 3.6,
        "track_rms_m": rms,
        "period_s": period,
        "wave_period_mps": -c_period,
        "wave_period_kmh": -c_period * 3.6,
        "collisions": collisions,
    }


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--vtype", required=True, help="attributes of the vType element")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    p.add_argument("--n", type=int, default=22)
    p.add_argument("--step", type=float, default=0.1)
    p.add_argument("--horizon", type=float, default=600.0)
    p.add_argument("--warmup", type=float, default=300.0)
    p.add_argument("--depart-speed", type=float, default=0.0)
    p.add_argument("--jitter", type=float, default=0.1, help="position jitter half-width [m]")
    p.add_argument("--check", action="store_true",
                   help="exit 1 unless every seed has a vehicle below 1 m/s after the warm-up and "
                        "a backward wave of 15-25 km/h by both estimates")
    args = p.parse_args()
    out = []
    for seed in args.seeds:
        r = run(args, seed)
        out.append(r)
        print("seed %d: first<1m/s at %s s, min v %.2f m/s, mean v %.2f m/s, wave %.1f km/h "
              "(track, rms %.1f m) / %.1f km/h (period %.1f s), collisions %d" % (
                  seed, r["t_first_below_1mps_s"], r["min_speed_after_warmup_mps"],
                  r["mean_speed_mps"], r["wave_track_kmh"], r["track_rms_m"],
                  r["wave_period_kmh"], r["period_s"], r["collisions"]), flush=True)
    print(json.dumps({"vtype": args.vtype, "horizon_s": args.horizon, "warmup_s": args.warmup,
                      "runs": out}, indent=1))
    if args.check:
        bad = [r["seed"] for r in out
               if not (r["min_speed_after_warmup_mps"] < 1.0
                       and -25.0 <= r["wave_track_kmh"] <= -15.0
                       and -25.0 <= r["wave_period_kmh"] <= -15.0
                       and r["collisions"] == 0)]
        if bad:
            print("check failed for seeds %s: no jam below 1 m/s, or wave outside 15-25 km/h "
                  "backward, or collisions" % bad, file=sys.stderr)
            sys.exit(1)
        print("check passed: jam below 1 m/s and backward wave 15-25 km/h in every seed",
              file=sys.stderr)


if __name__ == "__main__":
    main()
