"""The cost of one Gymnasium step of syncroad.gym.RingEnv against SUMO alone's step, side by
side in one run (the issue's target: at most 2x at N = 22).

* SUMO alone: the environment's own scenario (22 vehicles on the Sugiyama ring) stepped by
  libsumo in this process with nothing else: no reads, no commands, SUMO's model driving;
* syncroad.Simulation.step: the per-step API (a SUMO worker process, one observation and one
  command over a local connection per step);
* RingEnv.step: the same plus the environment's observation, action and reward.

The three run at once and are timed in turn, a block of steps each per round, so that the
machine's drifting speed (it changes by half within minutes on a shared machine) falls on all
three alike; the ratios are the medians over the rounds of each round's ratio.

Run it in an environment with the package and its extra (pip install '.[gym]'):

    .venv-py/bin/python python-host/bench_gym.py [ROUNDS [BLOCK]]

Prints one JSON line (ms per step, ratios); the guide's performance page quotes it.
"""

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import syncroad
from syncroad.gym import RingEnv, one_av_among_noisy_humans

ROUNDS = int(sys.argv[1]) if len(sys.argv) > 1 else 12
BLOCK = int(sys.argv[2]) if len(sys.argv) > 2 else 250
WARMUP = 200
HORIZON_S = (ROUNDS * BLOCK + WARMUP + 50) * 0.1


def start_sumo_alone(scenario):
    """libsumo on the scenario's network and routes (written by a syncroad run)."""
    import libsumo

    folder = Path(tempfile.mkdtemp(prefix="bench-gym-"))
    syncroad.run(scenario, out=folder / "run", plots=False, progress="never")
    routes = folder / "run" / "sumo" / "routes.rou.xml"
    libsumo.start(["sumo", "--net-file", scenario["sumo"]["net"], "--route-files", str(routes),
                   "--step-length", "0.1", "--no-step-log", "true", "--no-warnings", "true",
                   "--step-method.ballistic", "true", "--time-to-teleport", "-1"])
    return libsumo


def block_ms(step, n):
    """Milliseconds per call of `step` over `n` calls."""
    t0 = time.perf_counter()
    for _ in range(n):
        step()
    return 1e3 * (time.perf_counter() - t0) / n


def main():
    sc = one_av_among_noisy_humans(horizon_s=HORIZON_S)
    libsumo = start_sumo_alone(sc)
    sim = syncroad.Simulation(sc)
    env = RingEnv(sc)
    env.reset(seed=0)
    # The automated vehicle holds its speed (a = 0): a policy that kept accelerating would
    # drive it into the vehicle ahead within seconds, and SUMO's collision handling every
    # step (measured: +45 µs a step) would be timed instead of the environment.
    action = np.array([0.0], dtype=np.float32)
    cases = {
        "sumo_alone": libsumo.simulationStep,
        "simulation_step": sim.step,
        "gym_step": lambda: env.step(action),
    }
    for step in cases.values():
        block_ms(step, WARMUP)
    times = {k: [] for k in cases}
    for _ in range(ROUNDS):
        for k, step in cases.items():
            times[k].append(block_ms(step, BLOCK))
    sim.close()
    env.close()
    libsumo.close()
    ratio = lambda k: statistics.median(a / b for a, b in zip(times[k], times["sumo_alone"]))
    print(json.dumps({
        "vehicles": 22, "rounds": ROUNDS, "steps_per_block": BLOCK,
        **{f"{k}_ms": round(statistics.median(v), 4) for k, v in times.items()},
        "simulation_over_alone": round(ratio("simulation_step"), 2),
        "gym_over_alone": round(ratio("gym_step"), 2),
    }))


if __name__ == "__main__":
    main()
