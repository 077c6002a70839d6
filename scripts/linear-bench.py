#!/usr/bin/env python3
"""Times `syncroad check` and `syncroad stability` on networks of linear agents (the targets of
the guide's performance chapter): a ring of 1000 fourth-order agents for `check`, rings of 50
and 200 for `stability`. Agents are integrators behind three lags with a zero, their time
constants drawn from a fixed seed.

    python3 scripts/linear-bench.py OUT [--bin target/release/syncroad] [--repeat 3]
"""

import argparse
import json
import random
import subprocess
import time
from pathlib import Path


def agent(rng):
    rho = [1.0]
    for _ in range(3):
        t = rng.uniform(0.1, 0.6)
        rho = [a + b for a, b in zip(rho + [0.0], [0.0] + [t * x for x in rho])]
    return {"eta": [1.0, rng.uniform(0.0, 0.2)], "rho": rho}


def scenario(name, n, rng):
    return {
        "name": name, "backend": "native", "seed": 1, "step_s": 0.05, "horizon_s": 100,
        "vehicles": n, "road": {"type": "ring", "length_m": 30.0 * n},
        "model": {"type": "linear",
                  "graph": {"type": "bidirectional_ring", "gain_pred": 0.3, "gain_follow": 0.05},
                  "agents": [agent(rng) for _ in range(n)]},
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--bin", default="target/release/syncroad")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    rng = random.Random(1)
    cases = [("check", 1000), ("stability", 50), ("stability", 200)]
    for command, n in cases:
        path = a.out / f"linear-{n}.json"
        if not path.exists():
            path.write_text(json.dumps(scenario(f"linear-{n}", n, rng)))
        best = float("inf")
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            p = subprocess.run([a.bin, command, str(path), "--json"], capture_output=True, text=True)
            best = min(best, time.perf_counter() - t0)
        verdict = json.loads(p.stdout).get("verdict", "") if p.returncode in (0, 1) else p.stderr.strip()
        print(f"{command:9} N = {n:4}  {best:8.3f} s  {verdict}")


if __name__ == "__main__":
    main()
