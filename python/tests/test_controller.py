"""The user's own controller from Python: an object passed to ``syncroad.run`` drives the
vehicles in the SUMO worker and natively, exactly as its class named in the scenario does, and
a broken controller comes back as a clear error with the rows kept."""

import sys

import numpy as np
import pytest

import syncroad
from conftest import REPO

sys.path.insert(0, str(REPO / "examples" / "controllers"))
from follower_stopper import FollowerStopper  # noqa: E402

FILE = str(REPO / "examples" / "controllers" / "follower_stopper.py")


def ring(horizon_s=30):
    sc = syncroad.Scenario.load("scenarios/sugiyama-human.json")
    # The controller on every vehicle: without the file's humans-alone mixed block.
    d = dict(sc.data, horizon_s=horizon_s)
    del d["mixed"]
    return syncroad.Scenario.from_dict(d, base_dir=REPO / "scenarios")


def speeds(run):
    df = run.trajectories.to_pandas()
    return df.sort_values(["time_s", "vehicle"]).speed_mps.to_numpy()


class Raises:
    """A controller that fails at step 7 (defined here: loaded from this file by path)."""

    def step(self, obs):
        if obs.step == 7:
            raise ValueError(f"no command for {obs.ids[0]} at step {obs.step}")
        return obs.speed_mps


@pytest.mark.parametrize("backend", ["native", "sumo"])
def test_an_object_drives_as_its_class_named_in_the_scenario_does(tmp_path, backend):
    by_object = syncroad.run(ring(), backend=backend, out=tmp_path / "object",
                             controller=FollowerStopper(4.3), plots=False)
    by_block = syncroad.run(ring(), backend=backend, out=tmp_path / "block", plots=False,
                            controller={"python": f"{FILE}:FollowerStopper",
                                        "params": {"desired_speed_mps": 4.3}})
    a, b = speeds(by_object), speeds(by_block)
    assert len(a) == len(b) == 22 * 301
    assert np.array_equal(a, b)
    # The controller drove: a FollowerStopper at U = 4.3 m/s leaves the 4 m/s start.
    assert abs(a[-22:].mean() - 4.0) > 0.1
    m = by_object.metrics
    assert m.controller["label"] == "python:FollowerStopper"
    assert m.controller["source_file"] == FILE
    assert set(m.drivers) == {"python:FollowerStopper"}
    # The paper's certificate is of the model's law, not of this controller.
    assert m.certified is None


def test_the_objects_own_state_travels_with_it(tmp_path):
    # Changed after construction: the pickled state, not the constructor's arguments, drives.
    fs = FollowerStopper(4.3)
    fs.u = 6.0
    changed = syncroad.run(ring(), backend="native", out=tmp_path / "changed", controller=fs, plots=False)
    six = syncroad.run(ring(), backend="native", out=tmp_path / "six", plots=False,
                       controller={"python": f"{FILE}:FollowerStopper",
                                   "params": {"desired_speed_mps": 6.0}})
    assert np.array_equal(speeds(changed), speeds(six))


@pytest.mark.parametrize("backend", ["native", "sumo"])
def test_a_controller_that_raises_is_a_run_error_with_its_traceback_and_rows(tmp_path, backend):
    with pytest.raises(syncroad.RunError) as e:
        syncroad.run(ring(), backend=backend, out=tmp_path, controller=Raises(), plots=False)
    message = str(e.value)
    assert "the controller failed at t = 0.700 s (step 7)" in message
    assert f'File "{__file__}"' in message
    assert message.rstrip().endswith("ValueError: no command for v0 at step 7")
    assert e.value.run is not None
    assert len(e.value.run.trajectories) == 22 * 8


def test_a_class_without_a_file_is_refused_before_anything_runs(tmp_path):
    def make():
        class Local:
            def step(self, obs):
                return obs.speed_mps

        return Local()

    with pytest.raises(syncroad.ScenarioError, match="move the class into a .py file"):
        syncroad.run(ring(), out=tmp_path, controller=make())
    with pytest.raises(syncroad.ScenarioError, match="has no step method"):
        syncroad.run(ring(), out=tmp_path, controller=object())
    with pytest.raises(syncroad.ScenarioError, match=r"controller.python = \S*/nowhere.py:X: cannot read"):
        syncroad.run(ring(), out=tmp_path, controller={"python": "nowhere.py:X"})


class Exits:
    """A controller that ends its process at step 7 (defined here: loaded from this file)."""

    def step(self, obs):
        if obs.step == 7:
            import os

            os._exit(0)
        return obs.speed_mps


def test_a_native_controller_that_exits_its_process_leaves_this_interpreter_running(tmp_path):
    # The native simulator steps in this interpreter, but the controller in a process of its
    # own: its os._exit fails the run (the rows before it kept) instead of ending the caller,
    # as it ended a notebook's kernel before.
    with pytest.raises(syncroad.RunError, match="exited with code 0 during its step") as e:
        syncroad.run(ring(), backend="native", controller=Exits(), out=tmp_path / "out", plots=False)
    assert e.value.run is not None and not e.value.run.complete
    assert len(e.value.run.trajectories) == 22 * 8
    # And this interpreter goes on.
    assert syncroad.run(ring(), backend="native", controller=FollowerStopper(4.3), out=tmp_path / "next",
                        plots=False).complete
