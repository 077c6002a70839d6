"""The per-step API and the Gymnasium environment: a loop the caller writes drives exactly
as the same law given as a controller does, closing early keeps the rows with an incomplete
record, and the environment passes Gymnasium's own checker, repeats under a seed and runs
vectorised over worker processes."""

import subprocess
import sys

import numpy as np
import pytest

import syncroad
from conftest import REPO

sys.path.insert(0, str(REPO / "examples" / "controllers"))
from follower_stopper import FollowerStopper  # noqa: E402


def ring(horizon_s=20):
    sc = syncroad.Scenario.load("scenarios/sugiyama-human.json")
    # The caller drives every vehicle: without the file's humans-alone mixed block.
    d = dict(sc.data, horizon_s=horizon_s)
    del d["mixed"]
    return syncroad.Scenario.from_dict(d, base_dir=REPO / "scenarios")


def speeds(run):
    df = run.trajectories.to_pandas()
    return df.sort_values(["time_s", "vehicle"]).speed_mps.to_numpy()


@pytest.mark.parametrize("backend", ["native", "sumo"])
def test_a_loop_of_steps_drives_as_the_same_controller_does(tmp_path, backend):
    law = FollowerStopper(4.3)
    with syncroad.Simulation(ring(), backend=backend, out=tmp_path / "loop") as sim:
        steps = 0
        while not sim.done:
            sim.step(law.step(sim.observe()))
            steps += 1
    assert steps == 200
    assert sim.run.metrics.complete
    by_controller = syncroad.run(ring(), backend=backend, out=tmp_path / "controller",
                                 controller=FollowerStopper(4.3), plots=False)
    a, b = speeds(sim.run), speeds(by_controller)
    assert len(a) == 22 * 201
    assert np.array_equal(a, b)
    # Its record is the run's normal one, naming the stepping controller.
    assert sim.run.metrics.controller["label"] == "python:SimulationController"


def test_command_then_step_is_step_with_the_speeds(tmp_path):
    def drive(out, split):
        with syncroad.Simulation(ring(10), out=out) as sim:
            while not sim.done:
                obs = sim.observe()
                v = np.clip(obs.speed_mps + 0.1 * np.tanh(obs.gap_m - 8.0), 0.0, 9.0)
                if split:
                    sim.command(np.zeros_like(v))  # replaced by the next command
                    sim.command(v)
                    sim.step()
                else:
                    sim.step(v)
        return speeds(sim.run)

    a, b = drive(tmp_path / "a", False), drive(tmp_path / "b", True)
    assert len(a) == 22 * 101 and np.array_equal(a, b)
    with syncroad.Simulation(ring(10), out=tmp_path / "c") as sim:
        with pytest.raises(syncroad.ScenarioError, match="22 are needed"):
            sim.command([1.0])
        # A step without speeds after a refused command keeps the speeds.
        assert sim.step().step == 1


def test_closing_early_keeps_the_rows_with_an_incomplete_record(tmp_path, capfd):
    sim = syncroad.Simulation(ring(), backend="sumo", out=tmp_path)
    for _ in range(30):
        obs = sim.step()
    assert obs.step == 30 and obs.time_s == pytest.approx(3.0)
    with pytest.raises(syncroad.ScenarioError, match="22 are needed"):
        sim.step([1.0, 2.0])
    run = sim.close()
    assert sim.done
    assert run.metrics.complete is False
    assert run.metrics.stop["reason"] == "stopped_by_controller"
    assert "closed the simulation before its horizon" in run.metrics.error
    assert len(run.trajectories) == 22 * 31
    # A deliberate close is not an error: nothing on stderr (no traceback, no "error:" line).
    err = capfd.readouterr().err
    assert "error" not in err and "Traceback" not in err, err


def test_the_core_package_and_the_cli_never_import_gymnasium():
    code = "import sys, syncroad; syncroad.check('scenarios/ring-theorem1.json'); print('gymnasium' in sys.modules)"
    p = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert p.stdout.strip() == "False"


def test_two_simulations_step_side_by_side_in_one_process(tmp_path):
    # Each run collects its own report: the second once waited for the first to end, which
    # its caller, stepping both, never let happen.
    a = syncroad.Simulation(ring(12), out=tmp_path / "a")
    b = syncroad.Simulation(ring(12), out=tmp_path / "b")
    # libsumo runs one simulation per process: the first steps here, the second in a worker.
    assert a.in_process and not b.in_process
    with a, b:
        while not a.done:
            a.step()
            b.step()
    assert b.done and a.run.metrics.complete and b.run.metrics.complete
    # The same scenario and the same commands: the same run, whatever ran beside it and
    # wherever it stepped.
    assert np.array_equal(speeds(a.run), speeds(b.run))
    # The first one's end gave this process's libsumo back.
    with syncroad.Simulation(ring(12), out=tmp_path / "c") as c:
        assert c.in_process


def libsumo_comes_free(out, deadline):
    """Whether a Simulation started before `deadline` (monotonic) steps in this process: a
    run that held this process's libsumo has given it back."""
    import time

    while True:
        with syncroad.Simulation(ring(10), out=out) as sim:
            if sim.in_process or time.monotonic() >= deadline:
                return sim.in_process
        time.sleep(0.05)


@pytest.mark.parametrize("in_process", [True, False])
def test_a_simulation_dropped_without_close_closes_its_run(tmp_path, in_process):
    import gc
    import json
    import time

    sim = syncroad.Simulation(ring(), out=tmp_path / "dropped", in_process=in_process)
    assert sim.in_process == in_process
    for _ in range(15):
        sim.step()
    del sim
    gc.collect()
    # Its run ends as a close would end it: the record written, marked incomplete, with the
    # rows of the steps taken (nothing else would ever end it: the run waits for commands).
    metrics = tmp_path / "dropped" / "metrics.json"
    deadline = time.monotonic() + 120
    while not metrics.is_file() and time.monotonic() < deadline:
        time.sleep(0.05)
    record = json.loads(metrics.read_text())
    assert record["complete"] is False
    assert record["stop"]["reason"] == "stopped_by_controller"
    assert len(syncroad.Run(tmp_path / "dropped").trajectories) == 22 * 16
    # And this process's libsumo is free again for the next one.
    assert libsumo_comes_free(tmp_path / "next", deadline)


@pytest.mark.parametrize("in_process", [True, False])
def test_a_step_whose_wait_was_interrupted_is_received_before_the_next(tmp_path, in_process):
    # Ctrl-C can end the wait for the next observation after the commands went out: the run
    # has stepped. The next step() refuses commands computed before it, observe() then gives
    # the observation the run reached, and stepping goes on from there.
    with syncroad.Simulation(ring(), out=tmp_path, in_process=in_process) as sim:
        obs = sim.observe()
        assert obs.step == 0
        commands = obs.speed_mps.tobytes()
        # What an interrupted step leaves: the commands sent, their observation not taken.
        sim._pending = True
        if in_process:
            assert sim._handoff.step(commands) == 1
        else:
            sim._conn.send_bytes(commands)
        with pytest.raises(syncroad.RunError, match="interrupted after its commands went out"):
            sim.step()
        assert sim.observe().step == 1
        assert sim.step().step == 2
    assert len(sim.run.trajectories) == 22 * 3


def test_a_start_given_up_closes_the_run_and_frees_libsumo(tmp_path, monkeypatch):
    import time

    from syncroad import _simulation

    monkeypatch.setattr(_simulation, "START_TIMEOUT_S", 0.0)
    with pytest.raises(syncroad.RunError, match="did not start stepping within 0 s"):
        syncroad.Simulation(ring(), out=tmp_path / "given-up")
    monkeypatch.undo()
    # The abandoned run ends by itself (it would otherwise wait for its caller forever) and
    # gives this process's libsumo back.
    assert libsumo_comes_free(tmp_path / "next", time.monotonic() + 120)


@pytest.mark.parametrize("backend", ["native", "sumo"])
def test_a_run_stepped_in_this_process_is_the_run_stepped_in_a_worker(tmp_path, backend):
    # Commands that depend on what was observed, so that a difference in any row of any step
    # would show.
    runs = []
    for where in (True, False):
        with syncroad.Simulation(ring(), backend=backend, out=tmp_path / f"{where}",
                                 in_process=where) as sim:
            assert sim.in_process == where
            seen = []
            while not sim.done:
                obs = sim.observe()
                seen.append(np.concatenate([[obs.time_s, obs.step], obs.speed_mps, obs.gap_m,
                                            obs.leader_speed_mps, obs.odometer_m, obs.accel_mps2]))
                sim.step(np.clip(obs.speed_mps + 0.05 * np.tanh(obs.gap_m - 8.0), 0.0, 9.0))
        runs.append((np.array(seen), speeds(sim.run), sim.run.metrics.sync.verdict))
    (seen_a, v_a, verdict_a), (seen_b, v_b, verdict_b) = runs
    assert seen_a.shape == (200, 2 + 5 * 22)
    assert np.array_equal(seen_a, seen_b)
    assert np.array_equal(v_a, v_b) and verdict_a == verdict_b


def test_sumo_in_this_process_loads_without_tracis_wrappers_and_libsumo_sees_the_same_run(tmp_path):
    # A fresh interpreter: another test may have imported the libsumo package already.
    code = f"""
import sys
import syncroad
sc = syncroad.Scenario.load("scenarios/sugiyama-ring.json")
sc = syncroad.Scenario.from_dict(dict(sc.data, horizon_s=20), base_dir="scenarios")
with syncroad.Simulation(sc, backend="sumo", out={str(tmp_path / "run")!r}, in_process=True) as sim:
    for _ in range(5):
        sim.step(sim.observe().speed_mps)
    # SUMO was loaded without the package's TraCI wrappers (traci and sumolib).
    assert "traci" not in sys.modules and "sumolib" not in sys.modules, sorted(sys.modules)
    # A later import of the package wraps the same compiled module: the same simulation,
    # which the next step advances by one step.
    import libsumo
    assert libsumo.simulation.isLoaded()
    assert sorted(libsumo.vehicle.getIDList()) == sorted(sim.observe().ids)
    before = libsumo.simulation.getTime()
    sim.step(sim.observe().speed_mps)
    assert abs(libsumo.simulation.getTime() - before - 0.1) < 1e-9, (before, libsumo.simulation.getTime())
print("ok")
"""
    p = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True)
    assert p.returncode == 0 and p.stdout.strip() == "ok", p.stderr


def signalled_loop(folder):
    """A one-lane loop of eight 78 m edges (15 m/s) through a traffic light at node n2, built
    by the project's netconvert."""
    import math

    nodes = "".join(
        f'<node id="n{i}" x="{100 * math.cos(math.pi * i / 4):.3f}" y="{100 * math.sin(math.pi * i / 4):.3f}"'
        + (' type="traffic_light"' if i == 2 else "") + "/>"
        for i in range(8)
    )
    nodes += '<node id="north" x="0" y="250"/><node id="inner" x="0" y="20"/>'
    edges = "".join(f'<edge id="e{i}" from="n{i}" to="n{(i + 1) % 8}" numLanes="1" speed="15"/>' for i in range(8))
    edges += '<edge id="in" from="north" to="n2" numLanes="1" speed="15"/>'
    edges += '<edge id="out" from="n2" to="inner" numLanes="1" speed="15"/>'
    (folder / "tls.nod.xml").write_text(f"<nodes>{nodes}</nodes>")
    (folder / "tls.edg.xml").write_text(f"<edges>{edges}</edges>")
    netconvert = REPO / ".venv/lib/python3.11/site-packages/sumo/bin/netconvert"
    subprocess.run([str(netconvert), "--node-files", "tls.nod.xml", "--edge-files", "tls.edg.xml",
                    "-o", "tls.net.xml"], cwd=folder, check=True, capture_output=True)
    return syncroad.Scenario.from_dict({
        "name": "signalled-loop", "seed": 7, "step_s": 0.1, "horizon_s": 60, "vehicles": 6,
        "road": {"type": "loop", "edges": [f"e{i}" for i in range(8)]},
        "model": {"type": "delayed_driver",
                  "graph": {"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1},
                  "delay_s": 0.5},
        "initial": {"speed_mps": 8.0},
        "sumo": {"net": "tls.net.xml"},
    }, base_dir=folder)


def test_the_traffic_lights_ahead_are_observed_alike_in_this_process_and_in_a_worker(tmp_path):
    sc = signalled_loop(tmp_path)
    rows = []
    for where in (True, False):
        with syncroad.Simulation(sc, out=tmp_path / f"run-{where}", in_process=where) as sim:
            assert sim.in_process == where
            seen = []
            while not sim.done:
                obs = sim.observe()
                seen.append(np.concatenate([obs.signal_distance_m, obs.signal_stop, obs.speed_mps]))
                # 8 m/s, stopping 2 m before a red or yellow light within 40 m.
                red = (obs.signal_stop > 0) & (obs.signal_distance_m < 40.0)
                stop = np.sqrt(6.0 * np.maximum(obs.signal_distance_m - 2.0, 0.0))
                sim.step(np.where(red, np.minimum(8.0, stop), 8.0))
        rows.append(np.array(seen))
    a, b = rows
    assert a.shape == (600, 18)
    assert np.array_equal(a, b)
    # The light was seen, red and green, ahead of every vehicle at some step.
    assert np.all(np.isfinite(a[:, :6]).any(axis=0))
    assert (a[:, 6:12] == 1.0).any() and (a[:, 6:12] == 0.0).any()


def test_a_process_that_runs_its_own_libsumo_steps_the_simulation_in_a_worker(tmp_path):
    import libsumo

    net = REPO / "sumo-nets" / "sugiyama-ring.net.xml"
    libsumo.start(["sumo", "--net-file", str(net), "--no-step-log", "true"])
    try:
        with syncroad.Simulation(ring(10), out=tmp_path / "beside") as sim:
            # The caller's SUMO is left alone: the run steps in a worker.
            assert not sim.in_process
            while not sim.done:
                sim.step()
        assert libsumo.simulation.isLoaded()
        libsumo.simulationStep()
    finally:
        libsumo.close()
    assert sim.run.metrics.complete


gymnasium = pytest.importorskip("gymnasium")


def test_the_environment_passes_gymnasiums_checker_and_repeats_under_a_seed():
    from gymnasium.utils.env_checker import check_env

    from syncroad._rl import RING_UNIFORM_FLOW_MPS

    from syncroad.gym import RingEnv

    env = RingEnv()
    try:
        check_env(env, skip_render_check=True)
        assert env.action_space.shape == (1,) and env.observation_space.shape == (3,)
        runs = []
        for _ in range(2):
            obs, info = env.reset(seed=7)
            trace = [obs]
            for k in range(40):
                before = env._sim.observe().speed_mps.copy()
                x = 0.5 if k < 20 else -1.0
                obs, reward, terminated, truncated, _ = env.step(np.array([x]))
                assert 0.0 <= reward <= 1.0 and not terminated and not truncated
                # By the documented formulas: Flow's desired-velocity reward over every
                # vehicle, and the controlled vehicle (vehicle 0) commanded v + a Δt with
                # a = x · 2.6 m/s² (accel) or x · 4.5 m/s² (decel) — realised by SUMO within
                # its checks, so observed at most that fast.
                full = env._sim.observe()
                target = np.full(22, RING_UNIFORM_FLOW_MPS)
                best = np.linalg.norm(target)
                want = max(best - np.linalg.norm(full.speed_mps - target), 0.0) / best
                assert abs(reward - want) < 1e-12
                assert obs[0] == np.float32(min(full.speed_mps[0] / 30.0, 1.0))
                assert obs[1] == np.float32(min(full.gap_m[0] / full.ring_length_m, 1.0))
                assert obs[2] == np.float32(min(max(full.leader_speed_mps[0], 0.0) / 30.0, 1.0))
                a = x * (2.6 if x >= 0 else 4.5)
                assert full.speed_mps[0] <= max(before[0] + a * 0.1, 0.0) + 1e-9
                trace.append(obs)
            runs.append(np.array(trace))
        assert np.array_equal(runs[0], runs[1])
        # Another seed, other noise: the humans drive differently.
        env.reset(seed=8)
        other = [env.step(np.array([0.5]))[0] for _ in range(40)]
        assert not np.array_equal(runs[0][1:], np.array(other))
        # Without `out`, only the running episode's record is on disk.
        folders = [p.name for p in env._out.iterdir()]
        assert len(folders) == 1 and folders[0] == f"episode-{env._episodes - 1:05d}", folders
    finally:
        env.close()
    assert not env._out.exists()


def test_the_environment_refuses_an_action_of_the_wrong_size_not_finite_or_out_of_its_space():
    from syncroad.gym import RingEnv

    env = RingEnv()
    try:
        env.reset(seed=1)
        for bad in (np.array([0.1, 0.2]), np.array([])):
            with pytest.raises(ValueError, match=r"1 value\(s\) in \[-1, 1\] are needed, one per controlled vehicle \(v0\)"):
                env.step(bad)
        for bad in (np.array([np.nan]), np.array([np.inf]), np.array([1.01]), np.array([-2.0])):
            with pytest.raises(ValueError, match=r"action of v0 = .*: must be finite and in \[-1, 1\]"):
                env.step(bad)
        # Nothing was sent: the episode goes on from where it was.
        assert env._sim.observe().step == 0
        env.step(np.array([0.1]))
        assert env._sim.observe().step == 1
    finally:
        env.close()


def test_the_environment_keeps_its_episodes_records_when_given_a_folder(tmp_path):
    from syncroad.gym import RingEnv, one_av_among_noisy_humans

    env = RingEnv(one_av_among_noisy_humans(horizon_s=6.0), out=tmp_path / "episodes")
    try:
        env.reset(seed=1)
        truncated, info = False, {}
        while not truncated:
            # Full throttle from 4 m/s with 5.5 m to the vehicle ahead: contact within about
            # two seconds, but for SUMO's safe speed, which every vehicle of the default
            # scenario keeps.
            _, _, _, truncated, info = env.step(np.array([1.0]))
        m = info["run"].metrics
        assert m.complete and m.safe, m.unsafe_because
        assert m.safety_layer["mode"] == "sumo"
    finally:
        env.close()
    # The spaces' run, then the episode: both records kept.
    for name in ("episode-00000", "episode-00001"):
        assert (tmp_path / "episodes" / name / "metrics.json").is_file(), name


def test_four_environments_step_side_by_side_in_worker_processes():
    from syncroad.gym import RingEnv

    envs = gymnasium.vector.AsyncVectorEnv([RingEnv] * 4)
    try:
        obs, _ = envs.reset(seed=[1, 2, 3, 4])
        assert obs.shape == (4, 3)
        for _ in range(20):
            obs, reward, terminated, truncated, _ = envs.step(np.full((4, 1), 0.3, dtype=np.float32))
        assert reward.shape == (4,) and np.all((0 <= reward) & (reward <= 1))
        # Four seeds, four different rings.
        assert len({tuple(o) for o in obs}) == 4
    finally:
        envs.close()


def test_the_packaged_ring_is_the_repositorys():
    from pathlib import Path

    shipped = Path(syncroad.__file__).parent / "data" / "sugiyama-ring.net.xml"
    assert shipped.read_bytes() == (REPO / "sumo-nets" / "sugiyama-ring.net.xml").read_bytes()
