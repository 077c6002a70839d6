"""The guide's "From Python" chapter (docs/src/python.md): every Python example runs, in
order, in one namespace, from the repository root; its install block's one-liner (a console
block the guide test does not run: it makes a virtualenv) is the one test_cli_and_wheel.py runs
in a fresh virtualenv."""

import re

from conftest import REPO

PAGE = REPO / "docs" / "src" / "python.md"


def blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", PAGE.read_text(), flags=re.S)


def test_every_python_example_of_the_guide_runs(tmp_path, monkeypatch):
    code = blocks("python")
    assert len(code) >= 6
    # The examples write under out/ of the current folder: here a fresh one beside links to
    # the repository's scenarios and networks.
    monkeypatch.chdir(tmp_path)
    for d in ("scenarios", "sumo-nets"):
        (tmp_path / d).symlink_to(REPO / d)
    ns = {}
    for i, block in enumerate(code):
        exec(compile(block, f"{PAGE.name} python block {i + 1}", "exec"), ns)
    # What the comments of the examples say.
    assert ns["sc"].name == "sugiyama-ring" and ns["sc"].backend == "sumo"
    assert ns["r"].verdict == "synchronized" and ns["st"].verdict == "synchronizes"
    assert ns["rep"].certified is True
    assert len(ns["df"]) == ns["r"].trajectories.num_rows
    assert list(ns["cmp"].index) == ["protocol", "krauss"]
    assert list(ns["table"]["scale.gain"]) == [0.5, 1.0, 2.0]
    assert (tmp_path / "out/py-ring-figures/time_space.png").is_file()


def test_the_guides_one_liner_is_the_one_the_wheel_test_runs():
    from test_cli_and_wheel import ONE_LINER

    (shell,) = [b for b in blocks("console") if "pip install" in b]
    assert f'python -c "{ONE_LINER}"' in shell


def test_every_python_example_of_the_own_controller_page_runs(tmp_path, monkeypatch):
    page = REPO / "docs" / "src" / "own-controller.md"
    code = re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)
    # The first block is the included controller source (an mdBook include, not an example).
    code = [c for c in code if not c.startswith("{{#include")]
    assert len(code) == 3
    monkeypatch.chdir(tmp_path)
    for d in ("scenarios", "sumo-nets", "examples"):
        (tmp_path / d).symlink_to(REPO / d)
    ns = {}
    for i, block in enumerate(code):
        exec(compile(block, f"{page.name} python block {i + 1}", "exec"), ns)
    # What the comments of the examples say.
    assert ns["fs"].metrics.controller["label"] == "python:FollowerStopper"
    assert ns["fs"].metrics.drivers[0] == "python:FollowerStopper"
    assert (ns["loop"].metrics.complete, ns["loop"].verdict) == (True, "synchronized")
    assert len(ns["rewards"]) == 200 and 0 <= min(ns["rewards"]) <= max(ns["rewards"]) <= 1


def test_every_python_example_of_the_learning_page_runs(tmp_path, monkeypatch):
    page = REPO / "docs" / "src" / "learning.md"
    code = re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)
    assert len(code) == 2
    monkeypatch.chdir(tmp_path)
    ns = {}
    for i, block in enumerate(code):
        exec(compile(block, f"{page.name} python block {i + 1}", "exec"), ns)
    # What the comments of the examples say.
    assert ns["first"]["time_s"] == 75.0 and ns["info"]["time_s"] == 85.0
    assert ns["env"].agents == [] and ns["held"] != []
    assert ns["obs"]["v0"].shape == (3,) and set(ns["rewards"]) == {"v0", "v7", "v14"}


def test_the_readmes_python_example_runs(tmp_path, monkeypatch):
    text = (REPO / "README.md").read_text()
    (code,) = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    monkeypatch.chdir(tmp_path)
    for d in ("scenarios", "sumo-nets", "sweeps"):
        (tmp_path / d).symlink_to(REPO / d)
    ns = {}
    exec(compile(code, "README.md python block", "exec"), ns)
    # What the README says: the ring synchronizes, one row per driver, one per point.
    assert ns["run"].verdict == "synchronized"
    assert list(ns["df"].index) == ["protocol", "krauss", "krauss-0.9", "idm"]
    assert len(ns["table"]) == 256 and not (ns["table"]["status"] == "failed").any()
