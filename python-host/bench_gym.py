"""The cost of one Gymnasium step of syncroad.gym.RingEnv against SUMO alone's step, side by
side in one run (the issue's target: at most 2x at N = 22).

* SUMO alone: the environment's own scenario (22 vehicles on the Sugiyama ring) stepped by
  libsumo with nothing else: no reads, no commands, SUMO's model driving;
* syncroad.Simulation.step: the per-step API (SUMO in the caller's process, one observation
  and one command handed over per step);
* RingEnv.step: the same plus the environment's observation, action and reward;
* the last two again with ``in_process=False`` (SUMO in a worker process, the observation
  and the command over a local connection).

libsumo runs one simulation per process, so each case runs in a process of its own, as a
user's environment would. They start at once and are timed in turn, a block of steps each per
round (this process says whose turn it is), so that the machine's drifting speed (it changes
by half within minutes on a shared machine) falls on all alike; the ratios are the medians
over the rounds of each round's ratio.

Run it in an environment with the package and its extra (pip install '.[gym]'):

    .venv-py/bin/python python-host/bench_gym.py [ROUNDS [BLOCK]]

Prints one JSON line (ms per step, ratios); the guide's performance page quotes it.
"""

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SERVING = len(sys.argv) > 1 and sys.argv[1] == "--serve"
ROUNDS = int(sys.argv[1]) if len(sys.argv) > 1 and not SERVING else 12
BLOCK = int(sys.argv[2]) if len(sys.argv) > 2 and not SERVING else 250
WARMUP = 200
HORIZON_S = (ROUNDS * BLOCK + WARMUP + 50) * 0.1
CASES = ("sumo_alone", "simulation_step", "gym_step", "simulation_step_worker", "gym_step_worker")


def start_sumo_alone(scenario):
    """libsumo on the scenario's network and routes (written by a syncroad run)."""
    import libsumo

    import syncroad

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


def serve(case, horizon_s):
    """One case in this process: a block of steps for each number read from stdin, its ms per
    step written back."""
    import syncroad
    from syncroad.gym import RingEnv, one_av_among_noisy_humans

    sc = one_av_among_noisy_humans(horizon_s=horizon_s)
    in_process = not case.endswith("_worker")
    close = lambda: None
    if case == "sumo_alone":
        libsumo = start_sumo_alone(sc)
        step, close = libsumo.simulationStep, libsumo.close
    elif case.startswith("simulation_step"):
        sim = syncroad.Simulation(sc, in_process=in_process)
        assert sim.in_process == in_process
        step, close = sim.step, sim.close
    else:
        env = RingEnv(sc, in_process=in_process)
        assert env.in_process == in_process
        env.reset(seed=0)
        # The automated vehicle holds its speed (a = 0): a policy that kept accelerating would
        # drive it into the vehicle ahead within seconds, and SUMO's collision handling every
        # step (measured: +45 µs a step) would be timed instead of the environment.
        action = np.array([0.0], dtype=np.float32)
        step, close = (lambda: env.step(action)), env.close
    print("ready", flush=True)
    for line in sys.stdin:
        print(block_ms(step, int(line)), flush=True)
    close()


def main():
    procs = {
        k: subprocess.Popen([sys.executable, __file__, "--serve", k, str(HORIZON_S)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        for k in CASES
    }

    def block(k, n):
        p = procs[k]
        p.stdin.write(f"{n}\n")
        p.stdin.flush()
        return float(p.stdout.readline())

    for k, p in procs.items():
        assert p.stdout.readline().strip() == "ready", k
    for k in CASES:
        block(k, WARMUP)
    times = {k: [] for k in CASES}
    for _ in range(ROUNDS):
        for k in CASES:
            times[k].append(block(k, BLOCK))
    for p in procs.values():
        p.stdin.close()
        p.wait()
    ratio = lambda k: statistics.median(a / b for a, b in zip(times[k], times["sumo_alone"]))
    print(json.dumps({
        "vehicles": 22, "rounds": ROUNDS, "steps_per_block": BLOCK,
        **{f"{k}_ms": round(statistics.median(v), 4) for k, v in times.items()},
        **{f"{k}_over_alone": round(ratio(k), 2) for k in CASES[1:]},
    }))


if __name__ == "__main__":
    if SERVING:
        serve(sys.argv[2], float(sys.argv[3]))
    else:
        main()
