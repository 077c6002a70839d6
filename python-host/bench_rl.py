"""Environment steps per second of syncroad's learning environment against a TraCI-driven
ring environment of the same size, the way Flow drives SUMO, for one environment and for 2
and 8 side by side (the issue's target: at least 20× the TraCI environment's steps per second).

Equal work, per step, in both: 22 vehicles on the 230 m Sugiyama ring, one automated vehicle
commanded from the action, 21 stochastic humans (the ``human-noisy`` IDM: a = 1.3 m/s²,
b = 1.5 m/s², T = 0.8 s, s0 = 2 m, δ = 4, v0 = 30 m/s, σ = 0.2 m/s^1.5, step-consistent noise),
every vehicle's speed, gap and leader read, every vehicle commanded, SUMO's safe speed kept
(speed mode 25), the observation (speed, gap, speed ahead of the automated vehicle) and
Flow's desired-velocity reward computed.

* **syncroad**: ``syncroad.gym.RingEnv`` on ``syncroad._rl.ring_among_noisy_humans(1)``:
  libsumo in the environment's process, the humans computed in Rust;
* **TraCI** (Flow's way, ``flow/core/kernel``): SUMO as a separate process driven over
  TraCI's socket; one subscription per vehicle (speed, leader and gap) read with one
  ``getAllSubscriptionResults`` a step, the humans' IDM computed in Python and each vehicle
  commanded with ``slowDown(id, v', 1e-3)`` as Flow's ``apply_acceleration`` does.

Both start from the same routes (the ones a syncroad run of the scenario writes). One
environment: each kind in a process of its own, timed in turn in blocks (the machine's drift
falls on both alike), the ratio the median of the blocks' ratios. Two and eight environments:
``gymnasium.vector.AsyncVectorEnv`` of 2 and of 8, each kind in turn, total environment steps per
second over a few blocks.

    .venv-py/bin/python python-host/bench_rl.py [ROUNDS [BLOCK]]

Prints one JSON line; the guide's performance page quotes it.
"""

import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium
import numpy as np
from gymnasium import spaces

SERVING = len(sys.argv) > 1 and sys.argv[1] == "--serve"
ROUNDS = int(sys.argv[1]) if len(sys.argv) > 1 and not SERVING else 8
BLOCK = int(sys.argv[2]) if len(sys.argv) > 2 and not SERVING else 500
#: The vectorised cases: as many environments as this machine has cores, and 8.
VECTOR = (2, 8)
HORIZON_S = (ROUNDS * BLOCK * 2 + 1000) * 0.1

IDM = dict(a=1.3, b=1.5, T=0.8, s0=2.0, delta=4.0, v0=30.0, sigma=0.2)


def scenario():
    from syncroad._rl import ring_among_noisy_humans

    return ring_among_noisy_humans(1, HORIZON_S)


def routes():
    """The routes a syncroad run of the scenario writes: the same start for both kinds."""
    import syncroad

    folder = Path(tempfile.mkdtemp(prefix="bench-rl-"))
    syncroad.run(scenario(), out=folder / "run", plots=False, progress="never")
    return folder / "run" / "sumo" / "routes.rou.xml"


class TraciRingEnv(gymnasium.Env):
    """The ring over TraCI's socket, the way Flow's kernel drives SUMO (see the module)."""

    def __init__(self, rou=None, seed=0):
        import traci

        self.traci = traci
        self.rou = str(rou or routes())
        self.net = scenario()["sumo"]["net"]
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Box(0.0, 1.0, shape=(3,), dtype=np.float32)
        self.label = f"bench-{id(self)}"
        self.conn = None

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if self.conn is not None:
            self.conn.close()
        self.rng = np.random.default_rng(seed)
        from sumo import SUMO_HOME

        sumo = str(Path(SUMO_HOME) / "bin" / "sumo")
        self.traci.start([sumo, "--net-file", self.net, "--route-files", self.rou,
                          "--step-length", "0.1", "--no-step-log", "true", "--no-warnings", "true",
                          "--step-method.ballistic", "true", "--time-to-teleport", "-1"],
                         label=self.label, stdout=subprocess.DEVNULL)
        self.conn = self.traci.getConnection(self.label)
        self.conn.simulationStep()
        tc = self.traci.constants
        self.ids = list(self.conn.vehicle.getIDList())
        for v in self.ids:
            self.conn.vehicle.setSpeedMode(v, 25)
            self.conn.vehicle.subscribe(v, [tc.VAR_SPEED])
            self.conn.vehicle.subscribeLeader(v, 1000.0)
        self.conn.simulationStep()
        self._read()
        return self._obs(), {}

    def _read(self):
        tc = self.traci.constants
        res = self.conn.vehicle.getAllSubscriptionResults()
        self.speed = {v: res[v][tc.VAR_SPEED] for v in self.ids}
        self.leader = {v: res[v][tc.VAR_LEADER] for v in self.ids}

    def _obs(self):
        v0 = self.ids[0]
        lead, gap = self.leader[v0] or ("", math.inf)
        x = [self.speed[v0] / 30.0, gap / 230.0, (self.speed[lead] if lead else 0.0) / 30.0]
        return np.array([min(max(y, 0.0), 1.0) for y in x], dtype=np.float32)

    def step(self, action):
        p, dt = IDM, 0.1
        for k, v in enumerate(self.ids):
            s = self.speed[v]
            if k == 0:
                x = float(action[0])
                nxt = s + x * (2.6 if x >= 0 else 4.5) * dt
            else:
                lead, gap = self.leader[v] or ("", math.inf)
                acc = 1.0 - (s / p["v0"]) ** p["delta"]
                if lead:
                    vl = self.speed[lead]
                    star = p["s0"] + max(0.0, s * p["T"] + s * (s - vl) / (2 * math.sqrt(p["a"] * p["b"])))
                    acc -= (star / max(gap, 1e-3)) ** 2
                nxt = s + p["a"] * acc * dt + p["sigma"] * math.sqrt(dt) * self.rng.standard_normal()
            self.conn.vehicle.slowDown(v, max(nxt, 0.0), 1e-3)
        self.conn.simulationStep()
        self._read()
        speeds = list(self.speed.values())
        best = 3.45 * math.sqrt(len(speeds))
        reward = max(best - math.dist(speeds, [3.45] * len(speeds)), 0.0) / best
        return self._obs(), reward, False, False, {}

    def close(self):
        if self.conn is not None:
            self.conn.close()
            self.conn = None


def make(kind, rou):
    if kind == "syncroad":
        from syncroad.gym import RingEnv

        return RingEnv(scenario())
    return TraciRingEnv(rou)


def block_ms(step, n):
    t0 = time.perf_counter()
    for _ in range(n):
        step()
    return 1e3 * (time.perf_counter() - t0) / n


def serve(kind, rou):
    """One environment in this process: a block of steps per line read, its ms a step back."""
    env = make(kind, rou)
    env.reset(seed=1)
    action = np.array([0.0], dtype=np.float32)
    print("ready", flush=True)
    for line in sys.stdin:
        print(block_ms(lambda: env.step(action), int(line)), flush=True)
    env.close()


def one_each(rou):
    kinds = ("syncroad", "traci")
    procs = {k: subprocess.Popen([sys.executable, __file__, "--serve", k, str(rou)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
             for k in kinds}
    for k, p in procs.items():
        # TraCI prints its connection retries first.
        while (line := p.stdout.readline()) and line.strip() != "ready":
            pass
        assert line, k

    def block(k, n):
        procs[k].stdin.write(f"{n}\n")
        procs[k].stdin.flush()
        return float(procs[k].stdout.readline())

    for k in kinds:
        block(k, 200)
    times = {k: [] for k in kinds}
    for _ in range(ROUNDS):
        for k in kinds:
            times[k].append(block(k, BLOCK))
    for p in procs.values():
        p.stdin.close()
        p.wait()
    return times


def vectorised(kind, rou, count):
    """Environment steps per second of `count` environments in AsyncVectorEnv."""
    envs = gymnasium.vector.AsyncVectorEnv([lambda: make(kind, rou)] * count)
    try:
        envs.reset(seed=list(range(count)))
        action = np.zeros((count, 1), dtype=np.float32)
        for _ in range(100):
            envs.step(action)
        n = max(BLOCK, 200)
        t0 = time.perf_counter()
        for _ in range(n):
            envs.step(action)
        return count * n / (time.perf_counter() - t0)
    finally:
        envs.close()


def main():
    rou = routes()
    times = one_each(rou)
    ratio = statistics.median(t / s for s, t in zip(times["syncroad"], times["traci"]))
    out = {"vehicles": 22, "rounds": ROUNDS, "steps_per_block": BLOCK,
           "one_env_steps_per_s": {k: round(1e3 / statistics.median(v)) for k, v in times.items()},
           "one_env_syncroad_over_traci": round(ratio, 1)}
    for count in VECTOR:
        vec = {k: vectorised(k, rou, count) for k in ("syncroad", "traci")}
        out[f"{count}_envs_steps_per_s"] = {k: round(v) for k, v in vec.items()}
        out[f"{count}_envs_syncroad_over_traci"] = round(vec["syncroad"] / vec["traci"], 1)
    print(json.dumps(out))


if __name__ == "__main__":
    if SERVING:
        serve(sys.argv[2], sys.argv[3])
    else:
        main()
