#!/usr/bin/env python3
"""`syncroad stability` over graph families (rings, chains, random digraphs, leaders with
cycles, rings with chords, all-to-all, denser random digraphs) at N = 50, 200, 400,
heterogeneous gains and delays.

Writes the scenarios into OUT (deterministic: the same files on every machine) and, given one
or more binaries, times each scenario with each binary in turn (alternating, so that load
changes fall on both alike), with a timeout per run. Prints a Markdown table: wall time, the
exact verdict and whether the critical scale was certified.

    python3 scripts/stability-families.py OUT [--sizes 50,200,400] [--timeout 120] \\
        [--families random,ring] [--draws 1] \\
        [--bin before=/path/to/old/syncroad] [--bin after=target/release/syncroad]

`--draws K` draws each family K times (other gains, delays and arcs; the first draw is the
file of the plain table), so that one lucky graph does not stand for its family.
"""
import argparse
import json
import pathlib
import random
import subprocess
import time

# New families go at the end: a family's place seeds its draws.
FAMILIES = ["ring", "bidir", "chain", "random", "leader", "chords", "all", "random5", "random8"]
# Random arcs per driver of the random digraphs, besides the ring that keeps them connected.
RANDOM_ARCS = {"random": 3, "random5": 5, "random8": 8}
TITLES = {
    "ring": "one-way ring",
    "bidir": "bidirectional ring",
    "chain": "chain behind a leader",
    "random": "random digraph (ring + 3 random arcs per driver)",
    "leader": "leader with cycles (chain + back arcs + long arcs)",
    "chords": "bidirectional ring + chords to the opposite side",
    "all": "all-to-all",
    "random5": "denser random digraph (ring + 5 random arcs per driver)",
    "random8": "denser random digraph (ring + 8 random arcs per driver)",
}


def scenario(kind, n, draw=0):
    rng = random.Random(1000 + n + 7 * FAMILIES.index(kind) + 100_003 * draw)
    delays = [round(0.2 + 0.6 * rng.random(), 2) for _ in range(n)]
    model = {"type": "delayed_driver", "delay_s": delays}
    if kind == "ring":
        model["graph"] = {"type": "unidirectional_ring",
                          "gain": [round(0.3 + 0.4 * rng.random(), 3) for _ in range(n)]}
    elif kind == "bidir":
        model["graph"] = {"type": "bidirectional_ring",
                          "gain_pred": [round(0.4 + 0.4 * rng.random(), 3) for _ in range(n)],
                          "gain_follow": [round(0.1 + 0.3 * rng.random(), 3) for _ in range(n)]}
    elif kind == "chain":
        model["graph"] = {"type": "chain",
                          "gain": [round(0.4 + 0.4 * rng.random(), 3) for _ in range(n)]}
        model["leader"] = {"speed_mps": 10.0, "pinning": [0.5] + [0.0] * (n - 1)}
    elif kind == "all":
        model["graph"] = {"type": "all_to_all", "gain": round(1.0 / n, 6)}
    else:
        arcs = {}
        for i in range(n):
            if kind in RANDOM_ARCS:
                arcs[((i - 1) % n, i)] = round(0.2 + 0.3 * rng.random(), 3)
                for _ in range(RANDOM_ARCS[kind]):
                    j = rng.randrange(n)
                    if j != i and (j, i) not in arcs:
                        arcs[(j, i)] = round(0.05 + 0.2 * rng.random(), 3)
            elif kind == "leader":
                if i > 0:
                    arcs[(i - 1, i)] = round(0.4 + 0.3 * rng.random(), 3)
                    if i + 1 < n and rng.random() < 0.5:
                        arcs[(i + 1, i)] = round(0.1 + 0.2 * rng.random(), 3)
                    if rng.random() < 0.1:
                        j = rng.randrange(n)
                        if j != i:
                            arcs[(j, i)] = 0.1
            elif kind == "chords":
                arcs[((i - 1) % n, i)] = 0.5
                arcs[((i + 1) % n, i)] = 0.2
                if i % 5 == 0:
                    arcs[((i + n // 2) % n, i)] = 0.1
        model["graph"] = {"type": "edges", "edges": [
            {"from": f, "to": t, "weight": w} for (f, t), w in sorted(arcs.items())]}
    road = {"type": "straight"} if kind == "chain" else {"type": "ring", "length_m": 20.0 * n}
    name = f"{kind}{n}" + (f"-{draw}" if draw else "")
    return {"name": name, "seed": 1, "step_s": 0.01, "horizon_s": 10, "vehicles": n,
            "road": road, "model": model}


def critical_gain_scale(report):
    """The first `critical_gain_scale` of a `stability --json` report (ring or network)."""
    if isinstance(report, dict):
        if isinstance(report.get("critical_gain_scale"), (int, float)):
            return report["critical_gain_scale"]
        items = report.values()
    elif isinstance(report, list):
        items = report
    else:
        return None
    for v in items:
        found = critical_gain_scale(v)
        if found is not None:
            return found
    return None


def run(binary, path, timeout):
    start = time.monotonic()
    try:
        p = subprocess.run([binary, "stability", "--json", str(path)], capture_output=True,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"> {timeout:.0f} s", "—"
    wall = time.monotonic() - start
    try:
        r = json.loads(p.stdout)
        status = r.get("critical_scale_status", "")
        verdict = f'{r["verdict"]}, critical {status}'
        # The critical scale to nine digits, so that two builds' rows agree only when their
        # answers do (they may differ in the last digits, other pivots rounding otherwise).
        scale = critical_gain_scale(r)
        if scale is not None:
            verdict += f", c* {scale:.9g}"
    except (json.JSONDecodeError, KeyError):
        verdict = (p.stderr.strip().splitlines() or ["failed"])[-1][:60]
    return f"{wall:.2f} s", verdict


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--sizes", default="50,200,400")
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--draws", type=int, default=1)
    ap.add_argument("--bin", action="append", default=[], metavar="NAME=PATH")
    args = ap.parse_args()
    families = args.families.split(",")
    unknown = [f for f in families if f not in FAMILIES]
    if unknown or args.draws < 1:
        ap.error(f"--families {unknown} not among {FAMILIES}" if unknown
                 else f"--draws {args.draws}: at least 1")
    args.out.mkdir(parents=True, exist_ok=True)
    sizes = [int(s) for s in args.sizes.split(",")]
    bins = [b.split("=", 1) for b in args.bin]
    rows = []
    for kind in families:
        for n in sizes:
            for draw in range(args.draws):
                sc = scenario(kind, n, draw)
                path = args.out / f"{sc['name']}.json"
                text = json.dumps(sc)
                if not path.exists() or path.read_text() != text:
                    path.write_text(text)
                rows.append((kind, n, draw, path))
    if not bins:
        print(f"wrote {len(rows)} scenarios into {args.out}")
        return
    print("| family | N | " + " | ".join(name for name, _ in bins) + " | verdict |")
    print("|---|---:|" + "---:|" * len(bins) + "---|")
    for kind, n, draw, path in rows:
        cells, verdicts = [], []
        for name, binary in bins:
            wall, v = run(binary, path, args.timeout)
            cells.append(wall)
            verdicts.append((name, v))
        # One verdict when the binaries agree, else each with its binary's name.
        distinct = {v for _, v in verdicts}
        verdict = (distinct.pop() if len(distinct) == 1
                   else "; ".join(f"{name}: {v}" for name, v in verdicts))
        title = TITLES[kind] + (f", draw {draw}" if draw else "")
        print(f"| {title} | {n} | " + " | ".join(cells) + f" | {verdict} |", flush=True)


if __name__ == "__main__":
    main()
