"""The learning environments: PettingZoo's own API test passes with one agent per automated
vehicle, the Gymnasium view is the same episode summed over its agents, the registered
settings keep their documented warm-up and episode length, the named observations and
rewards are the published formulas (recomputed here from the run's own observation), one's
own reward and observation go through the same door, and every bad input is refused by name
with the episode's record kept."""

import json

import numpy as np
import pytest

import syncroad

gymnasium = pytest.importorskip("gymnasium")
pytest.importorskip("pettingzoo")

from syncroad._rl import ring_among_noisy_humans  # noqa: E402
from syncroad.gym import RingEnv  # noqa: E402
from syncroad.pettingzoo import ParallelTrafficEnv, parallel_env  # noqa: E402


def three(horizon_s=12.0):
    return ring_among_noisy_humans(3, horizon_s)


def test_the_rewards_desired_speed_is_the_uniform_flow_of_the_rings_humans():
    from syncroad._rl import RING_UNIFORM_FLOW_MPS, idm_uniform_flow_mps

    # Flow's IDM (T = 1 s) on 230 and 260 m: the published 3.4541 and 4.8159 m/s (Flow's ring
    # benchmarks; docs/src/published.md reproduces them in SUMO).
    assert round(idm_uniform_flow_mps(230, 22, time_headway_s=1.0), 4) == 3.4541
    assert round(idm_uniform_flow_mps(260, 22, time_headway_s=1.0), 4) == 4.8159
    # human-noisy's IDM (T = 0.8 s): the IDM's acceleration vanishes at the default.
    v, gap = RING_UNIFORM_FLOW_MPS, 230 / 22 - 5
    assert abs(1 - (v / 30) ** 4 - ((2 + 0.8 * v) / gap) ** 2) < 1e-12
    assert RingEnv.__init__.__kwdefaults__["desired_speed_mps"] == v
    assert ParallelTrafficEnv.__init__.__kwdefaults__["desired_speed_mps"] == v


def test_pettingzoos_api_test_passes_with_one_agent_per_automated_vehicle():
    from pettingzoo.test import parallel_api_test

    env = ParallelTrafficEnv(three(), warmup_s=2.0)
    try:
        # Three automated vehicles placed evenly among 22: vehicles 0, ⌊22/3⌋ and ⌊44/3⌋.
        assert env.possible_agents == ["v0", "v7", "v14"]
        parallel_api_test(env, num_cycles=1000)
        # Every agent is truncated together at the horizon: (12 − 2) s / 0.1 s steps.
        env.reset(seed=4)
        steps = 0
        while env.agents:
            _, _, term, trunc, infos = env.step({a: np.array([0.1], np.float32) for a in env.agents})
            steps += 1
        assert steps == 100 and all(trunc.values()) and not any(term.values())
        assert infos["v0"]["run"].metrics.complete
    finally:
        env.close()


def test_the_gymnasium_view_is_the_same_episode_with_the_agents_side_by_side():
    actions = [np.array([0.6, -0.4, 0.2]) if k % 7 else np.array([-1.0, 1.0, 0.0]) for k in range(60)]
    par = ParallelTrafficEnv(three(), warmup_s=1.0)
    gym = RingEnv(three(), warmup_s=1.0)
    try:
        obs_p, _ = par.reset(seed=9)
        obs_g, _ = gym.reset(seed=9)
        assert np.array_equal(obs_g, np.concatenate([obs_p[a] for a in par.possible_agents]))
        for x in actions:
            x = x.astype(np.float32)
            obs_p, rew_p, *_ = par.step(dict(zip(par.possible_agents, x)))
            obs_g, rew_g, *_ = gym.step(x)
            assert np.array_equal(obs_g, np.concatenate([obs_p[a] for a in par.possible_agents]))
            # The shared reward: every agent gets the Gymnasium view's one value.
            assert set(rew_p.values()) == {rew_g}
    finally:
        par.close()
        gym.close()


def run_episode(env, seed, steps=40):
    obs, _ = env.reset(seed=seed)
    trace = [np.concatenate([obs[a] for a in env.possible_agents])]
    for k in range(steps):
        obs, rew, *_ = env.step({a: np.array([0.3 if k < 20 else -0.5]) for a in env.agents})
        trace.append(np.concatenate([obs[a] for a in env.possible_agents] + [np.array(list(rew.values()))]))
    return trace


def test_a_seed_repeats_an_episode_and_another_seed_gives_another():
    env = parallel_env(None, scenario=three(), warmup_s=1.0)
    try:
        a, b, c = run_episode(env, 5), run_episode(env, 5), run_episode(env, 6)
        assert all(np.array_equal(x, y) for x, y in zip(a, b))
        assert not all(np.array_equal(x, y) for x, y in zip(a, c))
    finally:
        env.close()


def test_the_named_observations_and_rewards_are_the_published_formulas():
    env = ParallelTrafficEnv(three(), observation="flow-ring", reward="flow-ring", warmup_s=1.0)
    try:
        env.reset(seed=2)
        for k in range(30):
            x = [0.5, -0.25, 1.0] if k < 15 else [-1.0, 0.0, 0.3]
            sim = env._ep.sim
            before = sim.observe().speed_mps.copy()
            obs, rew, _, _, infos = env.step(dict(zip(env.agents, x)))
            o = sim.observe()
            # Flow's MultiAgentWaveAttenuationPOEnv: v/15, (v_ahead − v)/15, headway / length.
            for agent, i in zip(env.possible_agents, (0, 7, 14)):
                want = np.clip([o.speed_mps[i] / 15, (o.leader_speed_mps[i] - o.speed_mps[i]) / 15,
                                o.gap_m[i] / o.ring_length_m], -1, 1).astype(np.float32)
                assert np.array_equal(obs[agent], want)
            # Its reward: 4 mean(v)/20 − 4 mean|a|, a = x · 2.6 m/s² up, x · 4.5 m/s² down.
            a = [xi * (2.6 if xi >= 0 else 4.5) for xi in x]
            want_r = 4 * np.mean(o.speed_mps) / 20 - 4 * np.mean(np.abs(a))
            assert all(abs(r - want_r) < 1e-12 for r in rew.values())
            # The command the agents gave: v + a Δt, reached unless held back.
            for agent, i, ai in zip(env.possible_agents, (0, 7, 14), a):
                commanded = max(before[i] + ai * 0.1, 0.0)
                assert infos[agent]["unsafe"] == (commanded - o.speed_mps[i] > 1e-6)
    finally:
        env.close()


def test_the_registered_settings_keep_their_warm_up_and_episode_length():
    import syncroad.gym  # noqa: F401 - registers the settings

    env = gymnasium.make("syncroad/RingMulti-v0")
    try:
        assert env.spec.max_episode_steps == 3000
        assert env.observation_space.shape == (9,) and env.action_space.shape == (3,)
        _, info = env.reset(seed=1)
        # Flow's 750 warm-up steps of 0.1 s before the first step of the episode.
        assert info["time_s"] == pytest.approx(75.0, abs=1e-9)
        steps, truncated = 0, False
        while not truncated:
            _, _, terminated, truncated, info = env.step(np.zeros(3, np.float32))
            steps += 1
            assert not terminated
        # Gymnasium's time limit and the run's horizon end the episode at the same step: the
        # run ran to its end.
        assert steps == 3000 and info["run"].metrics.complete
        assert info["run"].metrics.horizon_s == pytest.approx(375.0)
    finally:
        env.close()
    stern = gymnasium.make("syncroad/RingStern-v0")
    try:
        # Stern et al.'s start: no warm-up, every vehicle at 4 m/s evenly spaced, the automated
        # vehicle under the safety filter.
        _, info = stern.reset(seed=1)
        assert info["time_s"] == 0.0
        o = stern.unwrapped._ep.sim.observe()
        assert np.all(o.speed_mps == 4.0) and np.ptp(o.gap_m) < 1e-9, (o.speed_mps, o.gap_m)
        assert stern.unwrapped._ep._data["safety"] == "filter"
    finally:
        stern.close()
    one = parallel_env("syncroad/Ring-v0")
    try:
        assert one.possible_agents == ["v0"]
    finally:
        one.close()
    with pytest.raises(syncroad.ScenarioError, match=r"'syncroad/Nope-v0': not registered; valid: syncroad/Ring-v0"):
        parallel_env("syncroad/Nope-v0")


def test_ones_own_reward_and_observation_go_through_the_same_door(tmp_path):
    from gymnasium import spaces

    def own_speed(view):
        # One reward per agent: its own speed, less one for a command the safety layer held back.
        return [view.obs.speed_mps[i] - float(u) for i, u in zip(view.agents, view.unsafe)]

    def gap_only(view, k):
        return [view.obs.gap_m[view.agents[k]]]

    gap_only.space = spaces.Box(0.0, np.inf, shape=(1,), dtype=np.float32)

    def unbounded(view, k):
        return [view.obs.speed_mps[view.agents[k]], view.obs.time_s]

    env = ParallelTrafficEnv(three(), reward=own_speed, observation=gap_only, out=tmp_path / "eps")
    try:
        assert env.observation_space("v7") is gap_only.space
        env.reset(seed=3)
        for _ in range(20):
            obs, rew, _, _, infos = env.step({a: np.array([1.0]) for a in env.agents})
            o = env._ep.sim.observe()
            for agent, i in zip(env.possible_agents, (0, 7, 14)):
                assert rew[agent] == o.speed_mps[i] - float(infos[agent]["unsafe"])
                assert obs[agent] == np.float32(o.gap_m[i])
        # Full throttle with 5.5 m to the vehicle ahead: SUMO's safe speed holds commands back.
        assert any(i["unsafe"] for i in infos.values())
    finally:
        env.close()
    gym = RingEnv(three(), observation=unbounded)
    try:
        assert gym.observation_space.shape == (6,) and np.isinf(gym.observation_space.high).all()
        obs, _ = gym.reset(seed=1)
        assert obs[1] == np.float32(0.0) and obs.dtype == np.float32
    finally:
        gym.close()
    with pytest.raises(syncroad.ScenarioError, match=r"reward = 'fast': not a named reward; valid: desired-velocity, flow-ring"):
        RingEnv(three(), reward="fast")
    with pytest.raises(syncroad.ScenarioError, match=r"observation = 'all': not a named observation; valid: local, flow-ring"):
        ParallelTrafficEnv(three(), observation="all")


def test_a_reward_that_raises_or_returns_nonsense_is_named_and_the_record_kept(tmp_path):
    def broken(view):
        if view.obs.time_s > 0.45:
            raise ZeroDivisionError("no traffic today")
        return 1.0

    env = ParallelTrafficEnv(three(), reward=broken)
    try:
        env.reset(seed=1)
        with pytest.raises(syncroad.RunError, match=r"reward .*broken raised ZeroDivisionError: no traffic today; the episode's record is kept in (\S+)") as e:
            for _ in range(10):
                env.step({a: np.array([0.0]) for a in env.agents})
        folder = e.value.out
        record = json.loads((folder / "metrics.json").read_text())
        # The run was closed where the reward failed: incomplete, its rows kept.
        assert record["complete"] is False and e.value.run is not None
        # The next episode starts afresh.
        env.reset(seed=2)
    finally:
        env.close()
    # Kept after the close of an environment whose folder is otherwise temporary.
    assert (folder / "metrics.json").is_file()

    for bad, why in ((lambda v: float("nan"), "nan"), (lambda v: [1.0, 2.0], r"\[1.0, 2.0\]")):
        env = ParallelTrafficEnv(three(), reward=bad, out=tmp_path / f"bad-{len(why)}")
        try:
            env.reset(seed=1)
            with pytest.raises(syncroad.RunError, match=rf"returned {why}; one finite number \(shared\) or 3 \(one per agent\) is needed"):
                env.step({a: np.array([0.0]) for a in env.agents})
        finally:
            env.close()


def test_bad_actions_and_a_closed_environment_are_refused_by_name_and_nothing_is_sent():
    env = ParallelTrafficEnv(three())
    try:
        with pytest.raises(syncroad.ScenarioError, match=r"no episode is running: call reset\(\) first"):
            env.step({})
        env.reset(seed=1)
        ok = {a: np.array([0.1]) for a in env.agents}
        cases = [
            (dict(ok, v7=np.array([0.1, 0.2])), r"action of v7 = array\(\[0.1, 0.2\]\): one value in \[-1, 1\] is needed"),
            (dict(ok, v7=np.array([np.nan])), r"action of v7 = nan: must be finite and in \[-1, 1\]"),
            (dict(ok, v14=1.5), r"action of v14 = 1.5: must be finite and in \[-1, 1\]"),
            (dict(ok, v14="fast"), r"action of v14 = 'fast': one value in \[-1, 1\] is needed"),
            ({"v0": 0.1}, r"one per live agent is needed; missing: v7, v14"),
            (dict(ok, v3=0.1), r"one per live agent is needed; not live agents: v3"),
            ([0.1, 0.1, 0.1], r"actions = \[0.1, 0.1, 0.1\]: a dict of one action per live agent \(v0, v7, v14\)"),
        ]
        for actions, message in cases:
            with pytest.raises(syncroad.ScenarioError, match=message):
                env.step(actions)
        # Nothing was sent: the episode goes on from where it was.
        assert env._ep.sim.observe().step == 0
        env.step(ok)
        assert env._ep.sim.observe().step == 1
        with pytest.raises(syncroad.ScenarioError, match=r"agent 'v1': not an agent of this environment; valid: v0, v7, v14"):
            env.observation_space("v1")
    finally:
        env.close()
    with pytest.raises(syncroad.RunError, match=r"the environment has been closed; make a new one"):
        env.step(ok)
    with pytest.raises(syncroad.RunError, match=r"the environment has been closed"):
        env.reset(seed=1)
    with pytest.raises(syncroad.ScenarioError, match=r"warmup_s = 30.0: must be ≥ 0 and below the scenario's horizon_s = 12"):
        ParallelTrafficEnv(three(), warmup_s=30.0)


def test_a_trained_policy_drives_a_scenario_as_it_drove_the_environment(tmp_path):
    import sys

    from conftest import REPO

    sys.path.insert(0, str(REPO / "examples" / "controllers"))
    from linear_policy import LinearPolicy

    # Accelerates towards the speed ahead: both signs on the perturbed ring.
    policy = {"weights": [-30.0, 0.0, 30.0], "bias": 0.0}
    law = LinearPolicy(policy)
    sc = ring_among_noisy_humans(1, 20.0)
    env = RingEnv(sc, out=tmp_path / "env")
    try:
        obs, _ = env.reset(seed=3)
        truncated, actions = False, []
        while not truncated:
            actions.append(law.act(obs))
            obs, _, _, truncated, info = env.step(np.array([actions[-1]]))
    finally:
        env.close()
    # The policy acted: braking and accelerating, not one saturated value.
    assert min(actions) < -0.1 and max(actions) > 0.1, (min(actions), max(actions))
    by_env = info["run"]
    by_controller = syncroad.run(dict(sc, seed=3), controller=law, out=tmp_path / "controller",
                                 plots=False)
    a = by_env.trajectories.to_pandas().sort_values(["time_s", "vehicle"]).speed_mps.to_numpy()
    b = by_controller.trajectories.to_pandas().sort_values(["time_s", "vehicle"]).speed_mps.to_numpy()
    assert len(a) == 22 * 201 and np.array_equal(a, b)


def test_the_training_example_runs_and_writes_a_policy_a_scenario_can_name(tmp_path, monkeypatch):
    import csv
    import sys

    from conftest import REPO

    pytest.importorskip("cma")
    sys.path.insert(0, str(REPO / "examples" / "learning"))
    import train_ring

    out = tmp_path / "quick"
    # A few thousand steps: two generations of four candidates, 300 steps each (it must run,
    # not learn).
    train_ring.main(["--out", str(out), "--generations", "2", "--population", "4",
                     "--episode-steps", "300"])
    rows = list(csv.DictReader(open(out / "learning_curve.csv")))
    assert [int(r["episodes"]) for r in rows] == [4, 8]
    assert all(0.0 <= float(r["worst_return"]) <= float(r["best_return"]) <= 1.0 for r in rows)
    assert (out / "learning_curve.png").is_file()
    policy = json.loads((out / "policy.json").read_text())
    assert len(policy["weights"]) == 3 and policy["trained"]["episodes"] == 8
    # The policy file is a controller's: a scenario names it and runs.
    monkeypatch.chdir(REPO)
    sc = dict(ring_among_noisy_humans(1, 10.0),
              controller={"python": "examples/controllers/linear_policy.py:LinearPolicy",
                          "params": {"policy": str(out / "policy.json")}})
    r = syncroad.run(sc, out=tmp_path / "run", plots=False)
    assert r.metrics.complete and r.metrics.drivers[0] == "python:LinearPolicy"


def test_an_environment_pickles_as_its_recipe_and_supersuit_vectorises_it(tmp_path):
    import pickle

    ss = pytest.importorskip("supersuit")
    env = ParallelTrafficEnv(three(), warmup_s=1.0, out=tmp_path / "eps")
    try:
        env.reset(seed=2)
        copy = pickle.loads(pickle.dumps(env))
        try:
            # A copy starts runs of its own, from the same recipe, its records beside the
            # original's.
            assert copy.possible_agents == env.possible_agents and copy._ep.sim is not env._ep.sim
            assert copy._ep.out == tmp_path / "eps" / "copy-001"
            a, _ = env.reset(seed=5)
            b, _ = copy.reset(seed=5)
            assert all(np.array_equal(a[k], b[k]) for k in a)
        finally:
            copy.close()
    finally:
        env.close()

    def trace(seed):
        vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(ParallelTrafficEnv(three())),
                                    2, num_cpus=2, base_class="gymnasium")
        try:
            obs, _ = vec.reset(seed=seed)
            rows = [obs]
            for _ in range(30):
                obs, reward, *_ = vec.step(np.full((6, 1), 0.2, dtype=np.float32))
                rows.append(obs)
            # Two environments of three agents each, each environment its own ring.
            assert obs.shape == (6, 3) and reward.shape == (6,)
            assert not np.array_equal(obs[:3], obs[3:])
            return np.array(rows)
        finally:
            vec.close()

    assert np.array_equal(trace(4), trace(4))


def test_without_the_extra_the_environments_say_how_to_install_it():
    import subprocess
    import sys

    for module, extra in (("syncroad.gym", "gym"), ("syncroad.pettingzoo", "pettingzoo")):
        # A module set to None in sys.modules cannot be imported: as if it were not installed.
        code = (f"import sys; sys.modules['pettingzoo'] = sys.modules['gymnasium'] = None\n"
                f"import {module}")
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert p.returncode != 0
        assert f"pip install 'syncroad[{extra}]'" in p.stderr, p.stderr
