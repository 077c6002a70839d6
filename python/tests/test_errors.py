"""Bad input raises ScenarioError with the CLI's message; a crashing worker raises RunError
and keeps its rows; Ctrl-C stops a run, keeps its rows and raises Interrupted."""

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import syncroad
from conftest import REPO, cli


def scenario(name="scenarios/ring-theorem1.json"):
    return json.loads((REPO / name).read_text())


def test_a_bad_field_is_named_as_the_cli_names_it(tmp_path):
    bad = scenario()
    bad["model"]["delay_s"] = -1
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(syncroad.ScenarioError) as e:
        syncroad.Scenario.load(path)
    p = cli("check", path)
    assert p.returncode == 2
    assert p.stderr.strip() == f"error: {e.value}"
    assert str(e.value).startswith("model.delay_s[0] = -1: must be ≥ 0")
    assert e.value.exit_code == 2
    # The same from a dict, and from every command given the file.
    with pytest.raises(syncroad.ScenarioError, match=r"^model\.delay_s\[0\] = -1: must be ≥ 0"):
        syncroad.Scenario.from_dict(bad)
    for call in (syncroad.run, syncroad.check, syncroad.stability):
        with pytest.raises(syncroad.ScenarioError, match=r"model\.delay_s\[0\]"):
            call(str(path))


def test_a_nested_field_and_an_unknown_one_are_named():
    sc = scenario()
    sc["initial"]["perturbation"]["gap_m"] = -1
    with pytest.raises(syncroad.ScenarioError, match=r"^initial\.perturbation\.gap_m = -1: must be a finite amplitude ≥ 0"):
        syncroad.Scenario.from_dict(sc)
    sc = scenario()
    sc["model"]["graph"]["gain_pred"] = -0.5
    with pytest.raises(syncroad.ScenarioError, match=r"^model\.graph\.gain_pred\[0\] = -0\.5: must be > 0"):
        syncroad.Scenario.from_dict(sc)
    sc = scenario()
    sc["vehicels"] = 3
    with pytest.raises(syncroad.ScenarioError, match="unknown field `vehicels`, expected one of"):
        syncroad.Scenario.from_dict(sc)


def test_a_relative_net_of_a_dict_resolves_against_base_dir(tmp_path):
    sc = scenario("scenarios/sugiyama-ring.json")
    ok = syncroad.Scenario.from_dict(sc, base_dir=REPO / "scenarios")
    assert Path(ok.data["sumo"]["net"]).is_file()
    with pytest.raises(syncroad.ScenarioError, match="sumo"):
        syncroad.run(syncroad.Scenario.from_dict(sc, base_dir=tmp_path))
    # The user's own files and a SUMO configuration resolve the same way: a configuration
    # is read when the scenario is validated, so a relative one must be found there.
    (tmp_path / "cfg").mkdir()
    shutil.copy(REPO / "sumo-nets/sugiyama-ring.net.xml", tmp_path / "ring.net.xml")
    (tmp_path / "mine.rou.xml").write_text("<routes/>\n")
    (tmp_path / "cfg/ring.sumocfg").write_text(
        '<configuration><input><net-file value="../ring.net.xml"/></input></configuration>\n'
    )
    own = dict(sc)
    own["sumo"] = {k: v for k, v in sc["sumo"].items() if k != "net"}
    own["sumo"].update({"config": "cfg/ring.sumocfg", "routes": ["mine.rou.xml"]})
    ok = syncroad.Scenario.from_dict(own, base_dir=tmp_path)
    assert Path(ok.data["sumo"]["config"]) == tmp_path / "cfg/ring.sumocfg"
    assert ok.data["sumo"]["routes"] == [str(tmp_path / "mine.rou.xml")]
    with pytest.raises(syncroad.ScenarioError, match="sumo.config"):
        syncroad.Scenario.from_dict(own, base_dir=REPO)


def test_options_are_checked_as_the_cli_checks_its_flags():
    with pytest.raises(syncroad.ScenarioError, match="backend"):
        syncroad.run("scenarios/ring-theorem1.json", backend="carla")
    with pytest.raises(syncroad.ScenarioError, match="--warmup-s"):
        syncroad.run("scenarios/ring-theorem1.json", warmup_s=1e6)
    with pytest.raises(syncroad.ScenarioError, match="--timeout-s"):
        # A SUMO option on a native scenario is refused, as by `syncroad run`.
        syncroad.run("scenarios/ring-theorem1.json", timeout_s=5)


def workers_of(pid):
    """Pids of this process's SUMO workers (`python -m syncroad._worker`)."""
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
            cmd = (d / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid == pid and b"syncroad._worker" in cmd:
            found.append(int(d.name))
    return found


def long_sugiyama(tmp_path):
    sc = scenario("scenarios/sugiyama-ring.json")
    sc["horizon_s"] = 100000
    return syncroad.Scenario.from_dict(sc, base_dir=REPO / "scenarios")


def test_a_crashing_worker_raises_and_keeps_its_rows(tmp_path):
    out = tmp_path / "out"
    killed = []

    def kill_when_running():
        t0 = time.time()
        while not (out / "sumo" / "sumo.log").exists() and time.time() - t0 < 60:
            time.sleep(0.02)
        time.sleep(2.5)
        for pid in workers_of(os.getpid()):
            os.kill(pid, signal.SIGSEGV)
            killed.append(pid)

    killer = threading.Thread(target=kill_when_running)
    killer.start()
    with pytest.raises(syncroad.RunError) as e:
        syncroad.run(long_sugiyama(tmp_path), out=out, record_every=10, plots=False)
    killer.join()
    assert len(killed) == 1, "one worker process, a child of this one"
    assert "SIGSEGV" in str(e.value)
    assert e.value.exit_code == 3 and e.value.out == out
    partial = e.value.run
    assert partial is not None and not partial.complete
    assert "SIGSEGV" in partial.metrics.error
    assert partial.verdict != "synchronized"
    rows = partial.trajectories.num_rows
    assert rows >= 22 * 10 and rows % 22 == 0
    # The API goes on: the next run works.
    assert syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "next").verdict == "synchronized"


CTRL_C = """
import json, sys, syncroad
sc = syncroad.Scenario.from_dict(json.loads(sys.argv[1]), base_dir=sys.argv[2])
try:
    syncroad.run(sc, out=sys.argv[3], record_every=10, plots=False)
    print(json.dumps({"interrupted": False}))
except syncroad.Interrupted as e:
    after = syncroad.run("scenarios/ring-theorem1.json", out=sys.argv[3] + "-after")
    print(json.dumps({"interrupted": True, "is_keyboard_interrupt": isinstance(e, KeyboardInterrupt),
                      "complete": e.run.complete, "error": e.run.metrics.error,
                      "rows": e.run.trajectories.num_rows, "after": after.verdict}))
"""


def test_ctrl_c_stops_a_run_keeps_its_rows_and_raises(tmp_path):
    sc = scenario("scenarios/sugiyama-ring.json")
    sc["horizon_s"] = 100000
    out = tmp_path / "out"
    child = subprocess.Popen(
        [sys.executable, "-c", CTRL_C, json.dumps(sc), str(REPO / "scenarios"), str(out)],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    t0 = time.time()
    while not (out / "sumo" / "sumo.log").exists() and time.time() - t0 < 60:
        time.sleep(0.02)
    time.sleep(2.0)
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=120)
    assert child.returncode == 0, stderr
    got = json.loads(stdout.strip().splitlines()[-1])
    assert got["interrupted"] and got["is_keyboard_interrupt"], got
    assert got["complete"] is False and "interrupted" in got["error"]
    assert got["rows"] >= 22 * 10
    assert got["after"] == "synchronized"  # the flag was cleared for the next command
