"""A PettingZoo environment over syncroad runs: one agent per automated vehicle (the optional
extra: ``pip install 'syncroad[pettingzoo]'``).

:class:`ParallelTrafficEnv` is a PettingZoo ``ParallelEnv`` on any scenario whose vehicles
stay on the road (a ring, a platoon, one's own closed network): each vehicle the scenario's
law would drive is an agent named by its vehicle id (``"v0"``, ...), and every step each live
agent gives its action. It is :class:`syncroad.gym.RingEnv` seen per agent: the same action
(one value in [-1, 1], the fraction of the vehicle type's deceleration or acceleration), the
same table of observations and rewards (a name or one's own callable; a shared reward is
given to every agent, a reward per agent to each), the same warm-up, records and seeds::

    from syncroad.pettingzoo import parallel_env
    env = parallel_env("syncroad/RingMulti-v0")
    obs, infos = env.reset(seed=1)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)
    env.close()

Every agent is truncated together at the scenario's horizon (``env.agents`` is then empty
until the next ``reset``), none is terminated. ``infos[agent]["unsafe"]`` says whether the
safety layer held the agent's last command back; the episode's record is in
``infos[agent]["run"]`` at its end.
"""

from __future__ import annotations

import functools
from typing import Any, Dict, List, Mapping, Optional, Tuple

import numpy as np

try:
    from gymnasium import spaces
    from pettingzoo import ParallelEnv
except ImportError as e:  # pragma: no cover - the message is the point
    raise ImportError(
        "syncroad.pettingzoo needs the optional extra: pip install 'syncroad[pettingzoo]' "
        "(pettingzoo and gymnasium 1.x)"
    ) from e

from syncroad._errors import ScenarioError
from syncroad._rl import SETTINGS, EpisodesEnv, action_value, setting


class ParallelTrafficEnv(EpisodesEnv, ParallelEnv):  # type: ignore[misc]
    """One agent per controlled vehicle of a syncroad scenario (see the module's text)."""

    metadata = {"render_modes": [], "name": "syncroad_traffic_v0", "is_parallelizable": True}

    default_automated = 3

    def _made(self) -> None:
        self.possible_agents: List[str] = list(self._ep.names)
        self.agents: List[str] = []
        self.render_mode = None
        self._action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self._started = False

    @functools.lru_cache(maxsize=None)  # noqa: B019 - one space object per agent, as PettingZoo asks
    def observation_space(self, agent: str) -> spaces.Box:
        self._known(agent)
        return self._ep.obs_space

    @functools.lru_cache(maxsize=None)  # noqa: B019
    def action_space(self, agent: str) -> spaces.Box:
        self._known(agent)
        return self._action_space

    def _known(self, agent: str) -> None:
        if agent not in self.possible_agents:
            raise ScenarioError(f"agent {agent!r}: not an agent of this environment; valid: "
                                f"{', '.join(self.possible_agents)}")

    def _observations(self) -> Dict[str, np.ndarray]:
        return dict(zip(self.possible_agents, self._ep.observations()))

    def reset(self, seed: Optional[int] = None, options: Optional[Mapping[str, Any]] = None
              ) -> Tuple[Dict[str, np.ndarray], Dict[str, Dict[str, Any]]]:
        if seed is None:
            # The next seed of the environment's own generator (seeded by the first seed it was
            # given), so that a seeded sequence of episodes repeats.
            if not hasattr(self, "_rng"):
                self._rng = np.random.default_rng()
            seed = int(self._rng.integers(0, 2**31 - 1))
        else:
            self._rng = np.random.default_rng(seed)
        view = self._ep.start(int(seed))
        self.agents = list(self.possible_agents)
        self._started = True
        info = {"time_s": float(view.obs.time_s), "seed": int(seed)}
        return self._observations(), {a: dict(info) for a in self.agents}

    def step(self, actions: Mapping[str, Any]) -> Tuple[
            Dict[str, np.ndarray], Dict[str, float], Dict[str, bool], Dict[str, bool],
            Dict[str, Dict[str, Any]]]:
        self._ep._refuse_closed()
        if not self._started:
            raise ScenarioError("no episode is running: call reset() first")
        if not self.agents:
            raise ScenarioError("every agent is done (truncated at the horizon): call reset()")
        if not isinstance(actions, Mapping):
            raise ScenarioError(f"actions = {actions!r}: a dict of one action per live agent "
                                f"({', '.join(self.agents)}) is needed")
        unknown = [str(a) for a in actions if a not in self.agents]
        missing = [a for a in self.agents if a not in actions]
        if unknown or missing:
            raise ScenarioError(
                "actions: one per live agent is needed"
                + (f"; not live agents: {', '.join(unknown)}" if unknown else "")
                + (f"; missing: {', '.join(missing)}" if missing else ""))
        xs = [action_value(actions[a], a) for a in self.possible_agents]
        ended = self._ep.act(xs)
        view = self._ep.view
        assert view is not None
        obs = self._observations()
        rewards = dict(zip(self.possible_agents, self._ep.rewards()))
        infos: Dict[str, Dict[str, Any]] = {a: {"time_s": float(view.obs.time_s), "unsafe": bool(u)}
                 for a, u in zip(self.possible_agents, view.unsafe)}
        if ended:
            run = self._ep.sim.run if self._ep.sim is not None else None
            for a in infos:
                infos[a]["run"] = run
        done = dict.fromkeys(self.possible_agents, ended)
        terminated = dict.fromkeys(self.possible_agents, False)
        if ended:
            self.agents = []
        return obs, rewards, terminated, done, infos

    def render(self) -> None:
        return None

    def close(self) -> None:
        self._ep.close()
        self.agents = []


def parallel_env(env_id: Optional[str] = None, **kwargs: Any) -> ParallelTrafficEnv:
    """A registered setting (``"syncroad/Ring-v0"``, ``"syncroad/RingMulti-v0"``, as
    ``gymnasium.make`` names them) as a PettingZoo environment; ``kwargs`` as
    :class:`ParallelTrafficEnv` takes them (``reward=``, ``observation=``, ``out=``, ...).
    Without an id, :class:`ParallelTrafficEnv`'s default."""
    if env_id is None:
        return ParallelTrafficEnv(**kwargs)
    s = setting(env_id)
    params: Dict[str, Any] = {"scenario": s.scenario(), "warmup_s": s.warmup_s, **s.kwargs}
    params.update(kwargs)
    return ParallelTrafficEnv(**params)


__all__ = ["ParallelTrafficEnv", "SETTINGS", "parallel_env"]
