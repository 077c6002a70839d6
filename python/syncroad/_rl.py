"""What syncroad's learning environments share (:mod:`syncroad.gym`, the single-agent view, and
:mod:`syncroad.pettingzoo`, one agent per automated vehicle): the episodes of runs they step,
an agent's action, the one table of observations and rewards (each a name from the table or
the user's callable, as a law is a name from the law table or the user's class), and the
registered settings of the field.

Only the optional extras import this module (it needs gymnasium's spaces); the core package
and the CLI never do.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
from gymnasium import spaces

from syncroad._errors import RunError, ScenarioError
from syncroad._scenario import PathLike, Scenario, ScenarioLike, as_scenario
from syncroad._simulation import Simulation

#: A command counts as held back (by SUMO's safe speed or syncroad's safety layer) when the
#: speed reached is below it by more than this [m/s]: far above SUMO's rounding, far below any
#: speed an action changes in one step.
HELD_BACK_TOL_MPS = 1e-6

#: The IDM that drives the automated vehicles during a warm-up: the ``human-noisy`` preset's
#: parameters without its noise (a = 1.3 m/s², T = 0.8 s; the rest Flow's ``IDMController``).
WARMUP_IDM = {"accel_mps2": 1.3, "decel_mps2": 1.5, "time_headway_s": 0.8, "min_gap_m": 2.0,
              "delta": 4.0, "desired_speed_mps": 30.0}


def idm_uniform_flow_mps(length_m: float, vehicles: int, vehicle_length_m: float = 5.0, *,
                         time_headway_s: float, min_gap_m: float = 2.0, delta: float = 4.0,
                         desired_speed_mps: float = 30.0) -> float:
    """The speed of the IDM's uniform flow on a ring: every gap ``length_m / vehicles −
    vehicle_length_m`` and every speed v with zero acceleration, ``1 − (v/v0)^δ − (s*/s)² =
    0``, ``s* = s0 + v T`` (bisection to the last bit; the acceleration is decreasing in v)."""
    gap = length_m / vehicles - vehicle_length_m
    lo, hi = 0.0, desired_speed_mps
    for _ in range(200):
        v = 0.5 * (lo + hi)
        acc = 1.0 - (v / desired_speed_mps) ** delta - ((min_gap_m + v * time_headway_s) / gap) ** 2
        lo, hi = (v, hi) if acc > 0.0 else (lo, v)
    return 0.5 * (lo + hi)


#: The reward's desired speed on the registered rings: the uniform flow of the ``human-noisy``
#: IDM (T = 0.8 s, s0 = 2 m, δ = 4, v0 = 30 m/s) with 22 cars of 5 m on 230 m, about 4.32 m/s
#: (Flow's own IDM, T = 1 s, gives Flow's 3.45 m/s on the same ring).
RING_UNIFORM_FLOW_MPS = idm_uniform_flow_mps(230.0, 22, 5.0, time_headway_s=0.8)


class View:
    """What an observation or a reward function is given after each step (and after
    ``reset``): the whole run's observation and the agents' part of it.

    * ``obs``: the :class:`syncroad.Simulation` observation of every vehicle (numpy arrays
      ``speed_mps``, ``gap_m``, ``leader_speed_mps``, ``accel_mps2``, ``odometer_m``, ... indexed
      like ``obs.ids``; ``dt_s``, ``time_s``, ``ring_length_m``);
    * ``agents``: each agent's index into those arrays; ``names``: its name (the vehicle's id);
    * ``accel_mps2``: the acceleration each agent's last action asked for [m/s²] (0 after a
      reset); ``commanded_mps``: the speed it was commanded;
    * ``held_back_mps``: by how much the speed reached is below the command (SUMO's safe speed
      or syncroad's safety layer held it back; ≥ 0), and ``unsafe``: ``held_back_mps`` above
      :data:`HELD_BACK_TOL_MPS`, so an action the safety layer had to correct is visible to
      the reward;
    * ``desired_speed_mps``, ``speed_scale_mps``, ``gap_scale_m``: the environment's settings.
    """

    def __init__(self, obs: SimpleNamespace, agents: Sequence[int], desired_speed_mps: float,
                 speed_scale_mps: float, gap_scale_m: float) -> None:
        self.obs = obs
        self.agents: Tuple[int, ...] = tuple(int(i) for i in agents)
        self.names: Tuple[str, ...] = tuple(str(obs.ids[i]) for i in self.agents)
        k = len(self.agents)
        # Plain floats, made into arrays only when a function asks: a step should cost little
        # beside SUMO's, and each numpy call costs about a microsecond whatever its size.
        self._accel = [0.0] * k
        self._commanded = [obs.speed_mps.item(i) for i in self.agents]
        self._held = [0.0] * k
        self.desired_speed_mps = desired_speed_mps
        self.speed_scale_mps = speed_scale_mps
        self.gap_scale_m = gap_scale_m

    @property
    def accel_mps2(self) -> "np.ndarray[Any, Any]":
        return np.array(self._accel, dtype=np.float64)

    @property
    def commanded_mps(self) -> "np.ndarray[Any, Any]":
        return np.array(self._commanded, dtype=np.float64)

    @property
    def held_back_mps(self) -> "np.ndarray[Any, Any]":
        return np.array(self._held, dtype=np.float64)

    @property
    def unsafe(self) -> "np.ndarray[Any, Any]":
        return np.array([h > HELD_BACK_TOL_MPS for h in self._held], dtype=bool)

    def stepped(self, obs: SimpleNamespace, accel: List[float], commanded: List[float]) -> None:
        """The view after a step that asked for ``accel`` and commanded ``commanded``."""
        self.obs = obs
        self._accel = accel
        self._commanded = commanded
        sp = obs.speed_mps.item
        self._held = [max(c - sp(i), 0.0) for c, i in zip(commanded, self.agents)]


# --- observations -------------------------------------------------------------------------


def _clip(x: float, lo: float, hi: float) -> float:
    # nan (nobody ahead: no speed) → lo; inf (no gap) → hi.
    return (hi if x > hi else x) if x > lo else lo


def _local(view: View, k: int) -> List[float]:
    o, i = view.obs, view.agents[k]
    vs, gs = view.speed_scale_mps, view.gap_scale_m
    return [_clip(o.speed_mps.item(i) / vs, 0.0, 1.0), _clip(o.gap_m.item(i) / gs, 0.0, 1.0),
            _clip(o.leader_speed_mps.item(i) / vs, 0.0, 1.0)]


def _flow_ring(view: View, k: int) -> List[float]:
    o, i = view.obs, view.agents[k]
    v, lead = o.speed_mps.item(i), o.leader_speed_mps.item(i)
    # Flow's leader-less vehicle observes itself: no speed difference.
    dv = (lead - v) if math.isfinite(lead) else 0.0
    length = float(o.ring_length_m or view.gap_scale_m)
    return [_clip(v / 15.0, -1.0, 1.0), _clip(dv / 15.0, -1.0, 1.0),
            _clip(o.gap_m.item(i) / length, -1.0, 1.0)]


@dataclass(frozen=True)
class Observation:
    """One agent's observation: ``fn(view, k)`` for agent ``k``, in ``space``."""

    name: str
    fn: Callable[[View, int], Any]
    space: Optional[spaces.Box]
    source: str = ""


#: The named observations: name → (function, bounds, size, what it is and where it comes from).
OBSERVATIONS: Dict[str, Observation] = {
    "local": Observation(
        "local", _local, spaces.Box(0.0, 1.0, shape=(3,), dtype=np.float32),
        "the agent's speed, its gap and the speed ahead, divided by speed_scale_mps, "
        "gap_scale_m (a ring's length) and speed_scale_mps, clipped to [0, 1]"),
    "flow-ring": Observation(
        "flow-ring", _flow_ring, spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32),
        "Flow's ring observation (MultiAgentWaveAttenuationPOEnv.get_state): v / 15, "
        "(v_ahead − v) / 15, gap / ring length, clipped to [-1, 1]"),
}


def _named(field: str, choice: Any, table: Mapping[str, Any], signature: str) -> Any:
    """The door for a name or a callable, as the law table's for a law: the table's entry of
    that name, or the callable itself; anything else is refused naming the field."""
    if isinstance(choice, str):
        if choice not in table:
            raise ScenarioError(f"{field} = {choice!r}: not a named {field}; valid: "
                                f"{', '.join(table)}, or a callable {signature}")
        return table[choice]
    if not callable(choice):
        raise ScenarioError(f"{field} = {choice!r}: a name ({', '.join(table)}) or a callable "
                            f"{signature} is needed")
    return choice


def observation_of(choice: Union[str, Callable[..., Any], Observation]) -> Observation:
    """A name from :data:`OBSERVATIONS`, or the user's ``fn(view, k)`` (its ``space``
    attribute, a gymnasium ``Box``, is its space; without one the space is unbounded, sized
    by the first observation)."""
    if isinstance(choice, Observation):
        return choice
    got = _named("observation", choice, OBSERVATIONS, "fn(view, k)")
    if isinstance(got, Observation):
        return got
    fn: Callable[[View, int], Any] = got
    space = getattr(fn, "space", None)
    if space is not None and not isinstance(space, spaces.Box):
        raise ScenarioError(f"observation {_name(fn)}: its space is {space!r}; a gymnasium "
                            "Box is needed (or no space attribute: unbounded)")
    return Observation(_name(fn), fn, space, "the caller's")


# --- rewards ------------------------------------------------------------------------------


def _desired_velocity(view: View) -> float:
    # flow.core.rewards.desired_velocity: max(‖v_des 1‖ − ‖v − v_des 1‖, 0) / ‖v_des 1‖ over
    # every vehicle (math.dist: one pass over plain floats).
    v = view.obs.speed_mps.tolist()
    best = view.desired_speed_mps * math.sqrt(len(v))
    return max(best - math.dist(v, [view.desired_speed_mps] * len(v)), 0.0) / best


def _flow_ring_reward(view: View) -> float:
    # Flow's ring reward (MultiAgentWaveAttenuationPOEnv.compute_reward): 4 · mean(v) / 20,
    # less 4 · mean |a| of the agents' asked accelerations.
    v = view.obs.speed_mps.tolist()
    a = math.fsum(abs(x) for x in view._accel) / len(view._accel) if view._accel else 0.0
    return 4.0 * (math.fsum(v) / len(v)) / 20.0 - 4.0 * a


@dataclass(frozen=True)
class Reward:
    """A reward: ``fn(view)`` gives one value shared by every agent or one per agent."""

    name: str
    fn: Callable[[View], Any]
    source: str = ""


#: The named rewards.
REWARDS: Dict[str, Reward] = {
    "desired-velocity": Reward(
        "desired-velocity", _desired_velocity,
        "Flow's desired-velocity reward (flow.core.rewards.desired_velocity): "
        "max(‖v_des‖ − ‖v − v_des‖, 0) / ‖v_des‖ over every vehicle, in [0, 1], shared"),
    "flow-ring": Reward(
        "flow-ring", _flow_ring_reward,
        "Flow's ring reward (MultiAgentWaveAttenuationPOEnv.compute_reward): "
        "4 · mean(v) / 20 − 4 · mean |a| over the agents' asked accelerations, shared"),
}


def reward_of(choice: Union[str, Callable[..., Any], Reward]) -> Reward:
    """A name from :data:`REWARDS`, or the user's ``fn(view)``."""
    if isinstance(choice, Reward):
        return choice
    got = _named("reward", choice, REWARDS, "fn(view)")
    if isinstance(got, Reward):
        return got
    fn: Callable[[View], Any] = got
    return Reward(_name(fn), fn, "the caller's")


def _name(fn: Any) -> str:
    return str(getattr(fn, "__qualname__", None) or getattr(fn, "__name__", None) or type(fn).__name__)


# --- actions ------------------------------------------------------------------------------


def action_value(x: Any, agent: str) -> float:
    """An agent's action as one float in [-1, 1], or a clear error naming the agent."""
    v: Optional[float] = None
    if type(x) is float:
        v = x
    elif isinstance(x, np.ndarray) and x.size == 1 and x.dtype.kind in "fiu":
        v = float(x.item())
    elif isinstance(x, (int, np.integer, np.floating)) and not isinstance(x, bool):
        v = float(x)
    if v is None:
        raise ScenarioError(f"action of {agent} = {x!r}: one value in [-1, 1] is needed")
    # float32 actions of a sampler lie exactly on the bounds; a tolerance for the rounding of
    # a policy's own arithmetic (a NaN fails the comparison too).
    if not -1.0 - 1e-6 <= v <= 1.0 + 1e-6:
        raise ScenarioError(f"action of {agent} = {v!r}: must be finite and in [-1, 1] (the "
                            "fraction of the vehicle type's deceleration below 0, of its "
                            "acceleration above 0)")
    return (1.0 if v > 1.0 else v) if v > -1.0 else -1.0


# --- episodes -----------------------------------------------------------------------------


class Episodes:
    """The runs an environment steps, one per episode: starts each (with its warm-up),
    applies the agents' actions, computes their observations and rewards, and keeps or removes
    each episode's record.

    An action x ∈ [-1, 1] asks for ``a = x · accel_mps2`` (x ≥ 0) or ``x · decel_mps2`` (the
    scenario's ``sumo`` block, SUMO's defaults 2.6 and 4.5 m/s²), and the vehicle is commanded
    ``max(v + a Δt, 0)``.
    """

    def __init__(self, scenario: ScenarioLike, *, observation: Any, reward: Any,
                 desired_speed_mps: float, speed_scale_mps: float, gap_scale_m: Optional[float],
                 warmup_s: float, backend: Optional[str], out: Optional[PathLike],
                 in_process: bool) -> None:
        # What a copy is made from (see reduce()).
        self.recipe: Dict[str, Any] = dict(
            observation=observation, reward=reward, desired_speed_mps=desired_speed_mps,
            speed_scale_mps=speed_scale_mps, gap_scale_m=gap_scale_m, warmup_s=warmup_s,
            backend=backend, out=out, in_process=in_process)
        self._copies = 0
        self.observation = observation_of(observation)
        self.reward = reward_of(reward)
        sc = as_scenario(scenario)
        self._data = dict(sc.data)
        self._base = sc.path.parent
        horizon = float(self._data.get("horizon_s", 0.0))
        if not (math.isfinite(warmup_s) and 0.0 <= warmup_s < horizon):
            raise ScenarioError(f"warmup_s = {warmup_s!r}: must be ≥ 0 and below the scenario's "
                                f"horizon_s = {horizon}")
        self.warmup_s = float(warmup_s)
        self.desired_speed_mps = float(desired_speed_mps)
        self.speed_scale_mps = float(speed_scale_mps)
        self._gap_scale = gap_scale_m
        self._backend = backend
        self._in_process = in_process
        sumo = self._data.get("sumo") or {}
        self.accel_mps2 = float(sumo.get("accel_mps2", 2.6))
        self.decel_mps2 = float(sumo.get("decel_mps2", 4.5))
        self._keep = out is not None
        self.out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="syncroad-gym-"))
        self.episodes = 0
        self.sim: Optional[Simulation] = None
        self.view: Optional[View] = None
        self.closed = False
        # The folders of episodes a user's function failed in: kept, even in a temporary folder.
        self._failures: List[Path] = []
        #: True while the episode's SUMO steps in this process.
        self.in_process = False
        # The agents are known once a run shows them: the first episode sizes the spaces.
        self.start(int(self._data.get("seed", 0)))
        assert self.view is not None
        self.names: Tuple[str, ...] = self.view.names
        self._obs_size: Optional[int] = None
        self.obs_space: spaces.Box = self._space()
        self._obs_size = int(self.obs_space.shape[0]) if self.obs_space.shape else 0

    def _space(self) -> spaces.Box:
        if self.observation.space is not None:
            return self.observation.space
        assert self.view is not None
        n = len(self._observe(0)) if self.view.agents else 0
        return spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)

    def reduce(self, cls: type) -> Tuple[Any, ...]:
        """How an environment of class ``cls`` over these episodes pickles: as its recipe (the
        scenario and the arguments it was made with), so that a copy (a vector wrapper's, in
        another process) starts runs of its own. The k-th copy of an environment that keeps
        its records keeps them in ``OUT/copy-00k``."""
        self._copies += 1
        kwargs = dict(self.recipe)
        if kwargs["out"] is not None:
            kwargs["out"] = str(Path(kwargs["out"]) / f"copy-{self._copies:03d}")
        return (rebuilt, (cls, dict(self._data), str(self._base), kwargs))

    def folder(self, episode: int) -> Path:
        return self.out / f"episode-{episode:05d}"

    def start(self, seed: int) -> View:
        """Ends the running episode and starts the next with ``seed``, past its warm-up."""
        self._refuse_closed()
        self.end()
        d = dict(self._data, seed=seed)
        folder = self.folder(self.episodes)
        self.episodes += 1
        self.sim = Simulation(Scenario.from_dict(d, base_dir=self._base), backend=self._backend,
                              out=folder, in_process=self._in_process)
        self.in_process = self.sim.in_process
        obs = self.sim.observe()
        agents = np.flatnonzero(np.asarray(obs.controlled, dtype=bool)).tolist()
        gap_scale = self._gap_scale or float(obs.ring_length_m or 100.0)
        self.view = View(obs, agents, self.desired_speed_mps, self.speed_scale_mps, gap_scale)
        self._warm_up()
        return self.view

    def _warm_up(self) -> None:
        """The warm-up: the agents drive as :data:`WARMUP_IDM` for ``warmup_s`` seconds."""
        assert self.sim is not None and self.view is not None
        steps = round(self.warmup_s / float(self.view.obs.dt_s))
        p = WARMUP_IDM
        a, b, t, s0, delta, v0 = (p["accel_mps2"], p["decel_mps2"], p["time_headway_s"],
                                  p["min_gap_m"], p["delta"], p["desired_speed_mps"])
        for _ in range(steps):
            o = self.view.obs
            speeds = o.speed_mps.copy()
            for i in self.view.agents:
                v, h, vl = o.speed_mps.item(i), o.gap_m.item(i), o.leader_speed_mps.item(i)
                free = 1.0 - (v / v0) ** delta
                if math.isfinite(h) and math.isfinite(vl):
                    s = s0 + max(0.0, v * t + v * (v - vl) / (2.0 * math.sqrt(a * b)))
                    free -= (s / max(h, 1e-3)) ** 2
                speeds[i] = max(v + a * free * o.dt_s, 0.0)
            nxt = self.sim._advance(speeds)
            if nxt is None:
                raise RunError("the run ended during its warm-up", out=self.folder(self.episodes - 1))
            self.view.obs = nxt
        self.view.stepped(self.view.obs, [0.0] * len(self.view.agents),
                          [self.view.obs.speed_mps.item(i) for i in self.view.agents])

    def act(self, xs: Sequence[float]) -> bool:
        """Applies one action per agent (checked: floats in [-1, 1]) and steps; True at the
        horizon (the run's record is then in ``self.sim.run``)."""
        self._refuse_closed()
        if self.sim is None or self.view is None:
            raise RunError("no episode is running: call reset() first")
        if self.sim.done:
            raise RunError("the episode has ended (truncated at its horizon): call reset()")
        view = self.view
        obs = view.obs
        speeds = obs.speed_mps.copy()
        dt, up, down = obs.dt_s, self.accel_mps2, self.decel_mps2
        accel: List[float] = []
        commanded: List[float] = []
        for i, x in zip(view.agents, xs):
            a = x * (up if x >= 0.0 else down)
            v = speeds.item(i) + a * dt
            speeds[i] = v if v > 0.0 else 0.0
            accel.append(a)
            commanded.append(speeds.item(i))
        nxt = self.sim._advance(speeds)
        if nxt is None:
            # The horizon: the last observation stands; the run's record is written.
            return True
        view.stepped(nxt, accel, commanded)
        return False

    def _observe(self, k: int) -> Any:
        """Agent ``k``'s observation as its function gives it, its size checked."""
        assert self.view is not None
        view, ob = self.view, self.observation
        try:
            x = ob.fn(view, k)
            n = len(x)
        except Exception as e:  # noqa: BLE001 - the user's function: named, record kept
            raise self._failed(f"observation {ob.name}",
                               f"for {view.names[k]} raised {type(e).__name__}: {e}") from e
        want = self._obs_size
        if want is not None and n != want:
            raise self._failed(f"observation {ob.name}",
                               f"for {view.names[k]} gave {n} value(s); its space has {want}")
        return x

    def observations(self) -> List["np.ndarray[Any, Any]"]:
        """Each agent's observation (float32)."""
        return [np.asarray(self._observe(k), dtype=np.float32).reshape(-1)
                for k in range(len(self.names))]

    def flat_observation(self) -> "np.ndarray[Any, Any]":
        """The agents' observations one after the other (float32): one array made."""
        flat: List[float] = []
        for k in range(len(self.names)):
            flat.extend(self._observe(k))
        return np.array(flat, dtype=np.float32)

    def rewards(self) -> List[float]:
        """Each agent's reward: the function's one value, shared, or its value per agent."""
        assert self.view is not None
        k = len(self.view.agents)
        try:
            r = self.reward.fn(self.view)
        except Exception as e:  # noqa: BLE001 - the user's function: named, record kept
            raise self._failed(f"reward {self.reward.name}", f"raised {type(e).__name__}: {e}") from e
        if type(r) is float:
            # The named rewards' case, at once.
            if math.isfinite(r):
                return [r] * k
            values = []
        else:
            try:
                values = ([float(r)] * k if np.ndim(r) == 0
                          else [float(x) for x in np.asarray(r, dtype=np.float64).reshape(-1)])
            except (TypeError, ValueError):
                values = []
        if len(values) != k or not all(math.isfinite(x) for x in values):
            raise self._failed(f"reward {self.reward.name}",
                               f"returned {repr(r)[:80]}; one finite number (shared) or {k} "
                               "(one per agent) is needed")
        return values

    def _failed(self, what: str, how: str) -> RunError:
        """The error of the user's function: the episode is closed, its record kept."""
        folder = self.folder(self.episodes - 1)
        run = self.sim.close() if self.sim is not None else None
        self.sim = None
        self._failures.append(folder)
        where = f"; the episode's record is kept in {folder}" if run is not None else ""
        return RunError(f"{what} {how}{where}", out=folder, run=run)

    def _refuse_closed(self) -> None:
        if self.closed:
            raise RunError("the environment has been closed; make a new one")

    def end(self) -> None:
        """Closes the running episode and removes its folder unless the records are kept."""
        if self.sim is None:
            return
        sim, self.sim = self.sim, None
        try:
            sim.close()
        finally:
            if not self._keep:
                shutil.rmtree(self.folder(self.episodes - 1), ignore_errors=True)

    def close(self) -> None:
        if self.closed:
            return
        self.end()
        self.closed = True
        if not self._keep and not self._failures:
            shutil.rmtree(self.out, ignore_errors=True)


def rebuilt(cls: type, data: Dict[str, Any], base_dir: str, kwargs: Dict[str, Any]) -> Any:
    """An environment made again from its recipe (:meth:`Episodes.reduce`)."""
    return cls(Scenario.from_dict(data, base_dir=base_dir), **kwargs)


class EpisodesEnv:
    """What both environments are made of: the scenario (by default the Sugiyama ring with
    ``default_automated`` automated vehicles among noisy humans) and the arguments of its
    :class:`Episodes`; an environment pickles as this recipe. A subclass sets its spaces or
    agents in ``_made``."""

    default_automated = 1

    def __init__(
        self,
        scenario: Optional[ScenarioLike] = None,
        *,
        reward: Union[str, Callable[..., Any]] = "desired-velocity",
        observation: Union[str, Callable[..., Any]] = "local",
        warmup_s: float = 0.0,
        desired_speed_mps: float = RING_UNIFORM_FLOW_MPS,
        speed_scale_mps: float = 30.0,
        gap_scale_m: Optional[float] = None,
        backend: Optional[str] = None,
        out: Optional[PathLike] = None,
        in_process: bool = True,
    ) -> None:
        if scenario is None:
            scenario = ring_among_noisy_humans(self.default_automated)
        self._ep = Episodes(scenario, observation=observation, reward=reward,
                            desired_speed_mps=desired_speed_mps, speed_scale_mps=speed_scale_mps,
                            gap_scale_m=gap_scale_m, warmup_s=warmup_s, backend=backend, out=out,
                            in_process=in_process)
        self._made()

    def _made(self) -> None:
        raise NotImplementedError

    def __reduce__(self) -> Any:
        # Pickled as its recipe: a copy starts runs of its own (vector wrappers copy it so).
        return self._ep.reduce(type(self))


# --- the registered settings ---------------------------------------------------------------


def ring_among_noisy_humans(automated: int = 1, horizon_s: float = 300.0, *,
                            start: str = "perturbed", safety: str = "sumo") -> Dict[str, Any]:
    """22 vehicles on the 230 m Sugiyama ring, ``automated`` of them controlled (placed evenly,
    the first one first), the others ``human-noisy``, all at 4 m/s.

    ``start``: ``"perturbed"`` (speeds ± 0.5 m/s and gaps ± 0.1 m drawn from the seed, as
    Flow perturbs its ring) or ``"uniform"`` (evenly spaced, every speed 4 m/s: Stern et al.'s
    start, so any jam forms from the humans' own noise). ``safety``: ``"sumo"`` (every vehicle
    keeps SUMO's safe speed, speed mode 25: Flow's default ``right_of_way``) or ``"filter"``
    (syncroad's safety filter under the automated vehicles, Gipps' safe speed with τ = 1 s),
    so an agent's action can slow its vehicle down but never drive it into the vehicle
    ahead."""
    if not (isinstance(automated, int) and 1 <= automated <= 22):
        raise ScenarioError(f"automated = {automated!r}: 1 to 22 vehicles of the 22 are needed")
    if start not in ("perturbed", "uniform"):
        raise ScenarioError(f"start = {start!r}: perturbed or uniform")
    if safety not in ("sumo", "filter"):
        raise ScenarioError(f"safety = {safety!r}: sumo or filter")
    initial: Dict[str, Any] = {"speed_mps": 4.0}
    if start == "perturbed":
        initial["perturbation"] = {"speed_mps": 0.5, "gap_m": 0.1}
    name = "gym-ring" if automated == 1 else f"gym-ring-{automated}av"
    return {
        "name": name if start == "perturbed" else f"{name}-uniform",
        "backend": "sumo",
        "seed": 0,
        "step_s": 0.1,
        "horizon_s": horizon_s,
        "vehicles": 22,
        "road": {"type": "ring", "length_m": 230},
        "model": {"type": "delayed_driver",
                  "graph": {"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1},
                  "delay_s": 0.5},
        "initial": initial,
        "mixed": {"penetration": automated / 22, "human": "human-noisy", "placement": "even"},
        "safety": safety,
        "sumo": {"net": str(Path(__file__).resolve().parent / "data" / "sugiyama-ring.net.xml")},
    }


@dataclass(frozen=True)
class Setting:
    """A registered environment: its id, scenario, warm-up and episode length."""

    id: str
    automated: int
    warmup_s: float
    episode_steps: int
    description: str
    source: str
    start: str = "perturbed"
    safety: str = "sumo"
    kwargs: Dict[str, Any] = field(default_factory=dict)

    def scenario(self) -> Dict[str, Any]:
        # The warm-up and the episode's steps of the scenario's Δt make the horizon.
        d = ring_among_noisy_humans(self.automated, start=self.start, safety=self.safety)
        d["horizon_s"] = self.warmup_s + self.episode_steps * d["step_s"]
        return d


#: The registered settings (``gymnasium.make(id)`` once :mod:`syncroad.gym` is imported;
#: :func:`syncroad.pettingzoo.parallel_env` takes the same ids).
SETTINGS: Dict[str, Setting] = {
    s.id: s
    for s in (
        Setting("syncroad/Ring-v0", 1, 75.0, 3000,
                "one automated vehicle among 21 human-noisy drivers on the 230 m Sugiyama ring",
                "Wu et al.'s mixed-autonomy ring as Flow trains it (singleagent_ring: Δt 0.1 s, "
                "750 warm-up steps, 3000 steps an episode); Flow draws the ring's length in "
                "220–270 m, here it is Sugiyama's 230 m"),
        Setting("syncroad/RingStern-v0", 1, 0.0, 3000,
                "one automated vehicle among 21 human-noisy drivers on the 230 m Sugiyama ring "
                "from a uniform start, under syncroad's safety filter",
                "Stern et al.'s experiment as syncroad's Stern sweeps run it (every vehicle at "
                "4 m/s, evenly spaced; no warm-up, so the automated vehicle acts before a jam "
                "forms; the sweeps' 600 s, here 300 s an episode)",
                start="uniform", safety="filter"),
        Setting("syncroad/RingMulti-v0", 3, 75.0, 3000,
                "three automated vehicles, evenly placed, among 19 human-noisy drivers on the "
                "230 m Sugiyama ring",
                "Flow's multi-agent ring (MultiAgentWaveAttenuationPOEnv: one agent per "
                "automated vehicle, a shared reward) with its warm-up and episode length"),
    )
}


def setting(env_id: str) -> Setting:
    if env_id not in SETTINGS:
        raise ScenarioError(f"environment {env_id!r}: not registered; valid: {', '.join(SETTINGS)}")
    return SETTINGS[env_id]
