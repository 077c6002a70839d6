#!/usr/bin/env python3
"""An open-road run against SUMO running the same demand alone.

The network (built here by the project's netconvert): a three-lane loop of eight 240 m edges
(25 m/s) whose lane 2 admits class `vip` only and lanes 0 and 1 every other class, with a
two-lane entry `in` joining lanes 0 and 1 at n0 (unregulated: nobody else drives them there)
and a two-lane exit `out` leaving them at n4: the two classes never share a lane. (With one
lane for the humans SUMO inserted at most about 1760 an hour on the entry.) syncroad's
scenario: 22 vehicles of class `vip` (`sumo.vclass`) driven by the delayed-driver law on lane 2
of the loop (the
Sugiyama ring's gains and delays), and `sumo.inflows` of human traffic from `in` to `out`
(VPH vehicles per hour, regular arrivals), Δt = 0.1 s, HORIZON s simulated, no plots.

Side by side, alternately, REPEATS times (the machine's speed drifts over minutes, so each ratio
is taken within one pair):
  * `syncroad run` of the scenario (the whole command: start-up, checks, the co-simulation loop
    with the law, SUMO's summary of every vehicle, the record);
  * SUMO alone, the `sumo` binary of the same virtualenv on the same network with the same two
    route files (syncroad's vehicles, then driven by SUMO's own model, and the inflow), the same
    step, end time and seed, no output.

    python3 scripts/bench-open-road.py OUT [--vph 2070] [--horizon 3600] [--repeats 3]

Prints each pair's walls and ratio, the vehicles that passed (SUMO's count of arrivals in the
syncroad run), and the median ratio.
"""
import argparse
import json
import math
import pathlib
import statistics
import subprocess
import time

REPO = pathlib.Path(__file__).resolve().parent.parent
VENV = REPO / ".venv"
SUMO_BIN = VENV / "lib/python3.11/site-packages/sumo/bin"


def build_network(out: pathlib.Path) -> pathlib.Path:
    nodes = ["<nodes>"]
    for i in range(8):
        a = 2 * math.pi * i / 8
        # The entry merges into a lane nobody else drives: no one to yield to at n0.
        kind = ' type="unregulated"' if i == 0 else ""
        nodes.append(f'  <node id="n{i}" x="{240 / (2 * math.sin(math.pi / 8)) * math.cos(a):.3f}" '
                     f'y="{240 / (2 * math.sin(math.pi / 8)) * math.sin(a):.3f}"{kind}/>')
    nodes += ['  <node id="a" x="700" y="-150"/>', '  <node id="b" x="-700" y="150"/>', "</nodes>"]
    edges = ["<edges>"]
    for i in range(8):
        edges.append(f'  <edge id="e{i}" from="n{i}" to="n{(i + 1) % 8}" numLanes="3" speed="25" '
                     'priority="2"><lane index="0" disallow="vip"/><lane index="1" disallow="vip"/>'
                     '<lane index="2" allow="vip"/></edge>')
    edges += ['  <edge id="in" from="a" to="n0" numLanes="2" speed="25" priority="1"/>',
              '  <edge id="out" from="n4" to="b" numLanes="2" speed="25" priority="1"/>',
              "</edges>"]
    # Lane by lane: the entry's two lanes feed the loop's two human lanes, and both leave by
    # the exit's two lanes (netconvert's own guess sent every exit through lane 0, a jam).
    cons = ["<connections>"]
    cons += [f'  <connection from="in" to="e0" fromLane="{k}" toLane="{k}"/>' for k in (0, 1)]
    cons += [f'  <connection from="e3" to="out" fromLane="{k}" toLane="{k}"/>' for k in (0, 1)]
    cons += ['  <connection from="e3" to="e4" fromLane="2" toLane="2"/>', "</connections>"]
    (out / "open.nod.xml").write_text("\n".join(nodes) + "\n")
    (out / "open.edg.xml").write_text("\n".join(edges) + "\n")
    (out / "open.con.xml").write_text("\n".join(cons) + "\n")
    net = out / "open.net.xml"
    subprocess.run([str(SUMO_BIN / "netconvert"), "--node-files", "open.nod.xml", "--edge-files",
                    "open.edg.xml", "--connection-files", "open.con.xml", "--no-turnarounds",
                    "true", "--no-warnings", "true", "-o", net.name], cwd=out, check=True)
    return net


def scenario(out: pathlib.Path, vph: float, horizon: float) -> pathlib.Path:
    base = json.loads((REPO / "scenarios/sugiyama-ring.json").read_text())
    sc = {
        "name": "open-road",
        "backend": "sumo",
        "seed": 42,
        "step_s": 0.1,
        "horizon_s": horizon,
        "vehicles": 22,
        "road": {"type": "loop", "through": "e1", "lane": 2},
        "model": base["model"],
        "initial": {"speed_mps": 8.0, "perturbation": {"speed_mps": 1.0}},
        "sumo": {"net": "open.net.xml", "vclass": "vip",
                 "inflows": [{"from": "in", "to": "out", "vehs_per_hour": vph}]},
    }
    path = out / "open-road.json"
    path.write_text(json.dumps(sc, indent=2))
    return path


def timed(cmd, cwd):
    t = time.monotonic()
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    wall = time.monotonic() - t
    if p.returncode not in (0, 1):  # 1: a verdict other than synchronized
        raise SystemExit(f"{cmd[0]} failed ({p.returncode}): {p.stderr[-2000:]}")
    return wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--vph", type=float, default=2070.0)
    ap.add_argument("--horizon", type=float, default=3600.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--bin", default=str(REPO / "target/release/syncroad"))
    args = ap.parse_args()
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    build_network(out)
    sc = scenario(out, args.vph, args.horizon)
    run_dir = out / "run"
    # No warm-up: every vehicle that passed in the hour counts.
    ours = [args.bin, "run", str(sc), "--out", str(run_dir), "--no-plots", "--warmup-s", "0"]
    # One run first: it writes the route files SUMO alone then reads.
    timed(ours, out)
    sumo_dir = run_dir / "sumo"
    routes = f"{sumo_dir / 'routes.rou.xml'},{sumo_dir / 'inflows.rou.xml'}"
    alone = [str(SUMO_BIN / "sumo"), "-n", str(out / "open.net.xml"), "-r", routes,
             "--begin", "0", "--end", str(args.horizon), "--step-length", "0.1", "--seed", "42",
             "--no-step-log", "true", "--no-warnings", "true"]
    ratios = []
    for i in range(args.repeats):
        a = timed(alone, out)
        b = timed(ours, out)
        ratios.append(b / a)
        print(f"pair {i + 1}: SUMO alone {a:.2f} s, syncroad run {b:.2f} s, ratio {b / a:.3f}",
              flush=True)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    allv = metrics.get("all_vehicles") or {}
    print(f"vehicles that passed (arrived) in the syncroad run: {allv.get('arrived')}, "
          f"at most {allv.get('vehicles_max')} on the road at once")
    print(f"median ratio syncroad/SUMO alone: {statistics.median(ratios):.3f}")


if __name__ == "__main__":
    main()
