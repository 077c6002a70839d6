"""Gymnasium environments over syncroad runs (the optional extra: ``pip install 'syncroad[gym]'``).

:class:`RingEnv` puts one or more controlled vehicles on any scenario, by default one
automated vehicle among 21 noisy human drivers on the Sugiyama ring (22 vehicles on 230 m,
``human-noisy``: Flow's IDM with Gaussian acceleration noise), and steps it through a
:class:`syncroad.Simulation`: the same run, record and files as ``syncroad run``. It is the
single-agent view of :class:`syncroad.pettingzoo.ParallelTrafficEnv` (one agent per
automated vehicle): the same actions, observations and rewards, one table of each.

* **Action**: one value in [-1, 1] per controlled vehicle, the fraction of the scenario's
  vehicle type's deceleration (below 0) or acceleration (above 0): ``a = x · accel_mps2`` for
  x ≥ 0, ``a = x · decel_mps2`` below; the commanded speed is ``max(v + a Δt, 0)``, which the
  default scenario's vehicles realise within SUMO's safe speed (its ``"safety": "sumo"``). An
  action outside [-1, 1], not finite or of the wrong shape is refused (``ScenarioError``).
* **Observation** (``observation=``): a name of :data:`syncroad._rl.OBSERVATIONS` (``local``,
  the default: each controlled vehicle's speed, gap and the speed ahead, scaled into [0, 1];
  ``flow-ring``: Flow's) or a callable ``fn(view, k)`` for agent ``k``; the agents'
  observations one after the other, float32.
* **Reward** (``reward=``): a name of :data:`syncroad._rl.REWARDS` (``desired-velocity``, the
  default: Flow's ``flow.core.rewards.desired_velocity`` with ``desired_speed_mps`` = 4.32 m/s,
  the uniform flow of the ``human-noisy`` IDM with 22 cars of 5 m on 230 m (Flow's 3.45 m/s is
  its own IDM's, T = 1 s, on the same ring); ``flow-ring``: Flow's ring
  reward) or a callable ``fn(view)`` giving one value or one per agent (their mean here). The
  view shows which commands the safety layer held back (``view.unsafe``).
* **Episode**: ``warmup_s`` seconds with the controlled vehicles driven by an IDM (not
  steps of the episode), then the steps to the scenario's horizon (``truncated`` at its end;
  never ``terminated``). ``reset(seed=s)`` starts the scenario with seed ``s`` (placements and
  noise follow it), so the same seed gives the same episode.
* **Records**: each episode is an ordinary run with its record (``info["run"]`` at the
  episode's end). With ``out=DIR`` they are kept, ``DIR/episode-00000``, ``episode-00001``, …;
  without it they go to a temporary folder of the environment, and an episode's folder is
  removed when the next episode starts and when the environment closes (a record of a few
  megabytes per episode would otherwise fill the disk over a training run). An episode in
  which the user's reward or observation raised is closed and its record kept, named in the
  ``RunError``.
* **Registered**: importing this module registers :data:`syncroad._rl.SETTINGS` with
  Gymnasium: ``gymnasium.make("syncroad/Ring-v0")`` (one automated vehicle, Flow's warm-up and
  episode length) and ``"syncroad/RingMulti-v0"`` (three).

SUMO steps in the environment's own process (``in_process=True``, the default; see
:class:`syncroad.Simulation`): a step costs little more than SUMO's own. libsumo runs one
simulation per process, so a second environment of the same process (an evaluation
environment beside the training one) steps its SUMO in a worker process, and
``gymnasium.vector.AsyncVectorEnv`` over several environments runs each in its own process,
side by side, each with SUMO in-process.
"""

from __future__ import annotations

import math
from typing import Any, Dict, Mapping, Optional, Tuple

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as e:  # pragma: no cover - the message is the point
    raise ImportError(
        "syncroad.gym needs the optional extra: pip install 'syncroad[gym]' (gymnasium 1.x)"
    ) from e

from syncroad._errors import ScenarioError
from syncroad._rl import SETTINGS, EpisodesEnv, action_value, ring_among_noisy_humans


def one_av_among_noisy_humans(horizon_s: float = 300.0) -> Dict[str, Any]:
    """The default environment's scenario: 22 vehicles on the 230 m Sugiyama ring, one of them
    controlled (an even placement puts it first), the others ``human-noisy``."""
    return ring_among_noisy_humans(1, horizon_s)


class RingEnv(EpisodesEnv, gymnasium.Env):
    """Controlled vehicles among the others of a syncroad scenario (see the module's text).
    ``RingEnv(scenario=None, *, reward, observation, warmup_s, desired_speed_mps,
    speed_scale_mps, gap_scale_m, backend, out, in_process)``: the arguments of
    :class:`syncroad._rl.EpisodesEnv`."""

    metadata = {"render_modes": []}

    def _made(self) -> None:
        self.desired_speed_mps = self._ep.desired_speed_mps
        self.speed_scale_mps = self._ep.speed_scale_mps
        k = len(self._ep.names)
        one = self._ep.obs_space
        self.action_space = spaces.Box(-1.0, 1.0, shape=(k,), dtype=np.float32)
        self.observation_space = spaces.Box(np.tile(one.low, k), np.tile(one.high, k),
                                            dtype=np.float32)

    @property
    def in_process(self) -> bool:
        """True while the episode's SUMO steps in this process (see syncroad.Simulation)."""
        return self._ep.in_process

    @property
    def _sim(self) -> Any:
        return self._ep.sim

    @property
    def _out(self) -> Any:
        return self._ep.out

    @property
    def _episodes(self) -> int:
        return self._ep.episodes

    def _observation(self) -> np.ndarray:
        return self._ep.flat_observation()

    def _reward(self) -> float:
        rs = self._ep.rewards()
        if not rs:
            return 0.0
        # A shared reward as it is (a mean of equal values can differ in its last bit).
        return rs[0] if rs.count(rs[0]) == len(rs) else math.fsum(rs) / len(rs)

    def reset(self, *, seed: Optional[int] = None, options: Optional[Mapping[str, Any]] = None
              ) -> Tuple[np.ndarray, Dict[str, Any]]:
        super().reset(seed=seed)
        # Without a seed, the next one of the environment's generator (itself seeded by the
        # first reset's seed), so that a seeded sequence of episodes repeats.
        s = seed if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        view = self._ep.start(s)
        return self._observation(), {"time_s": float(view.obs.time_s), "seed": s}

    def step(self, action: np.ndarray) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
        names = self._ep.names
        try:
            xs = np.asarray(action, dtype=np.float64).reshape(-1).tolist()
        except (TypeError, ValueError):
            xs = None
        if xs is None or len(xs) != len(names):
            raise ScenarioError(
                f"action = {action!r}: {len(names)} value(s) in [-1, 1] are needed, one per "
                f"controlled vehicle ({', '.join(names)})")
        # Each value a float now: checked, and clipped onto the bounds.
        xs = [action_value(x, n) for x, n in zip(xs, names)]
        ended = self._ep.act(xs)
        view = self._ep.view
        assert view is not None
        info: Dict[str, Any] = {"time_s": float(view.obs.time_s), "unsafe": view.unsafe}
        if ended:
            info["run"] = self._ep.sim.run if self._ep.sim is not None else None
        return self._observation(), self._reward(), False, ended, info

    def close(self) -> None:
        self._ep.close()


for _s in SETTINGS.values():
    gymnasium.register(
        id=_s.id, entry_point="syncroad.gym:RingEnv", max_episode_steps=_s.episode_steps,
        kwargs={"scenario": _s.scenario(), "warmup_s": _s.warmup_s, **_s.kwargs})
