"""TraCI-socket reference loop for syncroad's SUMO benchmark.

Drives a `sumo` subprocess through the pure-Python traci client doing, per step, the same
reads and writes as syncroad's in-process loop: speed, odometer and lane position of every
vehicle, a predecessor-following speed law, one setSpeed per vehicle (speed mode 32), one
simulation step. Prints one JSON line with the timing.

The reads come one of two ways (READS):
* `subscriptions` (the default): one getAllSubscriptionResults per step for every vehicle, as
  Flow reads its vehicles: the fair anchor;
* `per-call`: three getter calls per vehicle and step (getSpeed, getDistance,
  getLanePosition), one socket round trip each, as a naive TraCI loop does.

With CONTROLLER (`FILE.py:Class`, subscriptions only), the speeds come from that Python
controller's `step(obs)` (obs.speed_mps, obs.odometer_m as numpy arrays, obs.dt_s, obs.step,
obs.time_s, obs.ids), called once per step as Flow calls its controllers.

Usage: python traci_reference.py SUMO_BINARY NET ROUTES STEP_S SEED STEPS WARMUP_STEPS [READS [CONTROLLER]]
"""

import importlib.util
import json
import sys
import time
from types import SimpleNamespace

import traci
import traci.constants as tc


def main():
    sumo, net, routes, step_s, seed, steps, warmup = sys.argv[1:8]
    reads = sys.argv[8] if len(sys.argv) > 8 else "subscriptions"
    if reads not in ("subscriptions", "per-call"):
        sys.exit(f"READS = {reads!r}: expected subscriptions or per-call")
    controller = load_controller(sys.argv[9]) if len(sys.argv) > 9 else None
    if controller is not None and reads != "subscriptions":
        sys.exit("a CONTROLLER reads through subscriptions")
    step_s, steps, warmup = float(step_s), int(steps), int(warmup)
    traci.start([
        sumo, "--net-file", net, "--route-files", routes, "--step-length", repr(step_s),
        "--seed", seed, "--collision.action", "warn", "--collision.mingap-factor", "0",
        "--time-to-teleport", "-1", "--no-step-log", "true", "--duration-log.disable", "true",
        "--xml-validation", "never", "--step-method.ballistic", "true", "--no-warnings", "true",
    ])
    traci.simulationStep()  # insertion
    ids = sorted(traci.vehicle.getIDList(), key=lambda s: (s[0] != "l", int(s[1:]) if s[1:].isdigit() else 0))
    for v in ids:
        if reads == "subscriptions":
            traci.vehicle.subscribe(v, [tc.VAR_SPEED, tc.VAR_DISTANCE, tc.VAR_LANEPOSITION])
        traci.vehicle.setSpeedMode(v, 32)
        traci.vehicle.setLaneChangeMode(v, 0)
    n = len(ids)
    gain = 0.5
    start = None
    for k in range(steps):
        if k == warmup:
            start = time.perf_counter()
        if controller is not None:
            import numpy as np

            res = traci.vehicle.getAllSubscriptionResults()
            obs = SimpleNamespace(
                time_s=k * step_s, step=k, dt_s=step_s, ids=ids,
                speed_mps=np.array([res[v][tc.VAR_SPEED] for v in ids]),
                odometer_m=np.array([res[v][tc.VAR_DISTANCE] for v in ids]),
            )
            for v, x in zip(ids, controller.step(obs)):
                traci.vehicle.setSpeed(v, max(float(x), 0.0))
            traci.simulationStep()
            continue
        if reads == "subscriptions":
            res = traci.vehicle.getAllSubscriptionResults()
            speeds = [res[v][tc.VAR_SPEED] for v in ids]
        else:
            speeds = []
            for v in ids:
                speeds.append(traci.vehicle.getSpeed(v))
                traci.vehicle.getDistance(v)
                traci.vehicle.getLanePosition(v)
        for i, v in enumerate(ids):
            nxt = speeds[i] + step_s * gain * (speeds[i - 1] - speeds[i])
            traci.vehicle.setSpeed(v, max(nxt, 0.0))
        traci.simulationStep()
    wall = time.perf_counter() - start
    traci.close()
    timed = steps - warmup
    print(json.dumps({"vehicles": n, "reads": reads, "controller": controller is not None,
                      "timed_steps": timed, "wall_s": wall, "ms_per_step": 1e3 * wall / timed}))


def load_controller(spec):
    path, name = spec.rsplit(":", 1)
    module_spec = importlib.util.spec_from_file_location("bench_controller", path)
    module = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(module)
    return getattr(module, name)()


if __name__ == "__main__":
    main()
