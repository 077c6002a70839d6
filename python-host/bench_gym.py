"""The cost of one Gymnasium step of syncroad.gym.RingEnv against SUMO alone's step, side by
side in one run (the issue's target: at most 2x at N = 22).

* SUMO alone: the environment's own scenario (22 vehicles on the Sugiyama ring) stepped by
  libsumo in this process with nothing else: no reads, no commands, SUMO's model driving;
* syncroad.Simulation.step: the per-step API (a SUMO worker process, one observation and one
  command over a local connection per step);
* RingEnv.step: the same plus the environment's observation, action and reward.

Run it in an environment with the package and its extra (pip install '.[gym]'):

    .venv-py/bin/python python-host/bench_gym.py [STEPS]

Prints one JSON line (ms per step, ratios); the guide's performance page quotes it.
"""

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import syncroad
from syncroad.gym import RingEnv, one_av_among_noisy_humans

STEPS = int(sys.argv[1]) if len(sys.argv) > 1 else 3000
WARMUP = 200
HORIZON_S = (STEPS + WARMUP + 50) * 0.1


def sumo_alone_ms(scenario):
    """libsumo stepping the scenario's network and routes (written by a syncroad run)."""
    import libsumo

    folder = Path(tempfile.mkdtemp(prefix="bench-gym-"))
    syncroad.run(scenario, out=folder / "run", plots=False, progress="never")
    routes = folder / "run" / "sumo" / "routes.rou.xml"
    libsumo.start(["sumo", "--net-file", scenario["sumo"]["net"], "--route-files", str(routes),
                   "--step-length", "0.1", "--no-step-log", "true", "--no-warnings", "true",
                   "--step-method.ballistic", "true", "--time-to-teleport", "-1"])
    ms = per_step_ms(libsumo.simulationStep)
    libsumo.close()
    return ms


def per_step_ms(step):
    """Milliseconds per call of `step`, after WARMUP untimed calls."""
    for _ in range(WARMUP):
        step()
    t0 = time.perf_counter()
    for _ in range(STEPS):
        step()
    return 1e3 * (time.perf_counter() - t0) / STEPS


def simulation_ms(scenario):
    """syncroad.Simulation stepping with every speed held (the caller computes nothing)."""
    sim = syncroad.Simulation(scenario)
    ms = per_step_ms(sim.step)
    sim.close()
    return ms


def gym_ms(scenario):
    env = RingEnv(scenario)
    env.reset(seed=0)
    action = np.array([0.1], dtype=np.float32)
    ms = per_step_ms(lambda: env.step(action))
    env.close()
    return ms


def main():
    sc = one_av_among_noisy_humans(horizon_s=HORIZON_S)
    alone, sim, gym = sumo_alone_ms(sc), simulation_ms(sc), gym_ms(sc)
    print(json.dumps({
        "vehicles": 22, "steps": STEPS,
        "sumo_alone_ms": round(alone, 4), "simulation_step_ms": round(sim, 4), "gym_step_ms": round(gym, 4),
        "simulation_over_alone": round(sim / alone, 2), "gym_over_alone": round(gym / alone, 2),
    }))


if __name__ == "__main__":
    main()
