"""A Gymnasium environment over syncroad runs (the optional extra: ``pip install 'syncroad[gym]'``).

:class:`RingEnv` puts one or more controlled vehicles on any scenario, by default one
automated vehicle among 21 noisy human drivers on the Sugiyama ring (22 vehicles on 230 m,
``human-noisy``: Flow's IDM with Gaussian acceleration noise), and steps it through a
:class:`syncroad.Simulation`: the same run, record and files as ``syncroad run``.

* **Action**: one value in [-1, 1] per controlled vehicle, the fraction of the scenario's
  vehicle type's deceleration (below 0) or acceleration (above 0): ``a = x · accel_mps2`` for
  x ≥ 0, ``a = x · decel_mps2`` below; the commanded speed is ``max(v + a Δt, 0)``, which the
  default scenario's vehicles realise within SUMO's safe speed (its ``"safety": "sumo"``).
* **Observation**: for each controlled vehicle, its speed, the gap to the vehicle ahead and
  that vehicle's speed, each divided by a scale (``speed_scale_mps``, the ring's length or
  ``gap_scale_m``) so values lie in [0, 1]; shape ``(3 k,)``, float32.
* **Reward**: Flow's desired-velocity reward (``flow.core.rewards.desired_velocity``):
  ``max(‖v_des 1‖ − ‖v − v_des 1‖, 0) / ‖v_des 1‖`` over every vehicle, in [0, 1];
  ``desired_speed_mps`` defaults to 3.45 m/s, the uniform flow of Flow's IDM with 22 cars of
  5 m on 230 m.
* **Episode**: the scenario's horizon (``truncated`` at its end; never ``terminated``).
  ``reset(seed=s)`` starts the scenario with seed ``s`` (placements and noise follow it), so
  the same seed gives the same episode.
* **Records**: each episode is an ordinary run with its record (``info["run"]`` at the
  episode's end). With ``out=DIR`` they are kept, ``DIR/episode-00000``, ``episode-00001``, …;
  without it they go to a temporary folder of the environment, and an episode's folder is
  removed when the next episode starts and when the environment closes (a record of a few
  megabytes per episode would otherwise fill the disk over a training run).

SUMO steps in the environment's own process (``in_process=True``, the default; see
:class:`syncroad.Simulation`): a step costs little more than SUMO's own. libsumo runs one
simulation per process, so a second environment of the same process (an evaluation
environment beside the training one) steps its SUMO in a worker process, and
``gymnasium.vector.AsyncVectorEnv`` over several environments runs each in its own process,
side by side, each with SUMO in-process.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple

import gymnasium
import numpy as np
from gymnasium import spaces

from syncroad._scenario import PathLike, Scenario, ScenarioLike, as_scenario
from syncroad._simulation import Simulation

def one_av_among_noisy_humans(horizon_s: float = 300.0) -> Dict[str, Any]:
    """The default environment's scenario: 22 vehicles on the 230 m Sugiyama ring, one of them
    controlled (an even placement puts it first), the others ``human-noisy``. Every vehicle
    keeps SUMO's safe speed (``"safety": "sumo"``, speed mode 25: Flow's default
    ``right_of_way``), so an agent's action can slow its vehicle down but never drive it into
    the vehicle ahead."""
    return {
        "name": "gym-ring",
        "backend": "sumo",
        "seed": 0,
        "step_s": 0.1,
        "horizon_s": horizon_s,
        "vehicles": 22,
        "road": {"type": "ring", "length_m": 230},
        "model": {"type": "delayed_driver",
                  "graph": {"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1},
                  "delay_s": 0.5},
        "initial": {"speed_mps": 4.0, "perturbation": {"speed_mps": 0.5, "gap_m": 0.1}},
        "mixed": {"penetration": 1 / 22, "human": "human-noisy", "placement": "even"},
        "safety": "sumo",
        "sumo": {"net": str(Path(__file__).resolve().parent / "data" / "sugiyama-ring.net.xml")},
    }


class RingEnv(gymnasium.Env):
    """Controlled vehicles among the others of a syncroad scenario (see the module's text)."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: Optional[ScenarioLike] = None,
        *,
        desired_speed_mps: float = 3.45,
        speed_scale_mps: float = 30.0,
        backend: Optional[str] = None,
        out: Optional[PathLike] = None,
        in_process: bool = True,
    ) -> None:
        sc = as_scenario(scenario if scenario is not None else one_av_among_noisy_humans())
        self._data = dict(sc.data)
        self._base = sc.path.parent
        self.desired_speed_mps = float(desired_speed_mps)
        self.speed_scale_mps = float(speed_scale_mps)
        self._backend = backend
        self._in_process = in_process
        #: True while the episode's SUMO steps in this process (see syncroad.Simulation).
        self.in_process = False
        sumo = self._data.get("sumo") or {}
        self._accel = float(sumo.get("accel_mps2", 2.6))
        self._decel = float(sumo.get("decel_mps2", 4.5))
        self._sim: Optional[Simulation] = None
        # Where the episodes' records go: kept under `out`, or each removed after its episode
        # from a temporary folder of this environment's own.
        self._keep = out is not None
        self._out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="syncroad-gym-"))
        self._episodes = 0
        # The controlled vehicles' indices into the observation's arrays.
        self._idx: np.ndarray = np.zeros(0, dtype=np.intp)
        self._cl: List[int] = []
        self._desired: List[float] = []
        # The controlled vehicles are known once a run shows them: start one to size the spaces.
        obs = self._start(int(self._data.get("seed", 0)))
        k = len(self._idx)
        self.gap_scale_m = float(obs.ring_length_m or 100.0)
        n = len(obs.ids)
        # The reward's best value, ‖v_des 1‖, once.
        self._best = self.desired_speed_mps * math.sqrt(n)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(k,), dtype=np.float32)
        self.observation_space = spaces.Box(0.0, 1.0, shape=(3 * k,), dtype=np.float32)

    def _start(self, seed: int) -> Any:
        self._end_episode()
        d = dict(self._data, seed=seed)
        folder = self._out / f"episode-{self._episodes:05d}"
        self._episodes += 1
        self._sim = Simulation(Scenario.from_dict(d, base_dir=self._base), backend=self._backend,
                               out=folder, in_process=self._in_process)
        self.in_process = self._sim.in_process
        obs = self._sim.observe()
        self._idx = np.flatnonzero(np.asarray(obs.controlled, dtype=bool))
        self._cl = self._idx.tolist()
        self._desired = [self.desired_speed_mps] * len(obs.ids)
        return obs

    def _observation(self, obs: Any) -> np.ndarray:
        # Plain floats for the few controlled vehicles: a Gymnasium step should cost little
        # beside SUMO's, and a numpy call costs a microsecond whatever its size (the guide's
        # performance page measures both).
        sp, gap, lead = obs.speed_mps.item, obs.gap_m.item, obs.leader_speed_mps.item
        c, vs, gs = self._cl, self.speed_scale_mps, self.gap_scale_m
        # Nobody ahead: the gap is the scale (inf → 1 after scaling) and the speed ahead 0
        # (nan → 0); each value clipped to [0, 1].
        x = [sp(i) / vs for i in c] + [gap(i) / gs for i in c] + [lead(i) / vs for i in c]
        return np.array([(1.0 if v > 1.0 else v) if v > 0.0 else 0.0 for v in x], dtype=np.float32)

    def _reward(self, obs: Any) -> float:
        # ‖v − v_des 1‖ (math.dist: one pass over plain floats).
        d = math.dist(obs.speed_mps.tolist(), self._desired)
        return max(self._best - d, 0.0) / self._best

    def reset(self, *, seed: Optional[int] = None, options: Optional[Mapping[str, Any]] = None
              ) -> Tuple[np.ndarray, Dict[str, Any]]:
        super().reset(seed=seed)
        # Without a seed, the next one of the environment's generator (itself seeded by the
        # first reset's seed), so that a seeded sequence of episodes repeats.
        s = seed if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        obs = self._start(s)
        return self._observation(obs), {"time_s": float(obs.time_s), "seed": s}

    def step(self, action: np.ndarray) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
        assert self._sim is not None, "call reset() first"
        obs = self._sim.observe()
        # x clipped to [-1, 1]; a = x · accel above 0, x · decel below; v' = max(v + a Δt, 0).
        xs = np.asarray(action, dtype=np.float64).reshape(-1).tolist()
        if len(xs) != len(self._cl) or not all(math.isfinite(x) for x in xs):
            raise ValueError(
                f"action = {action!r}: {len(self._cl)} finite value(s) in [-1, 1] are needed, "
                "one per controlled vehicle"
            )
        speeds = obs.speed_mps.copy()
        dt, up, down = obs.dt_s, self._accel, self._decel
        for i, x in zip(self._cl, xs):
            x = (1.0 if x > 1.0 else x) if x > -1.0 else -1.0
            v = speeds.item(i) + x * (up if x >= 0.0 else down) * dt
            speeds[i] = v if v > 0.0 else 0.0
        nxt = self._sim._advance(speeds)
        if nxt is None:
            # The horizon: the last observation stands; the run's record is written.
            run = self._sim.run
            return self._observation(obs), self._reward(obs), False, True, {"run": run}
        return self._observation(nxt), self._reward(nxt), False, False, {"time_s": float(nxt.time_s)}

    def _end_episode(self) -> None:
        """Closes the running episode, and removes its folder unless the records are kept."""
        if self._sim is None:
            return
        sim, self._sim = self._sim, None
        try:
            sim.close()
        finally:
            if not self._keep:
                shutil.rmtree(self._out / f"episode-{self._episodes - 1:05d}", ignore_errors=True)

    def close(self) -> None:
        self._end_episode()
        if not self._keep:
            shutil.rmtree(self._out, ignore_errors=True)
