"""Bad input raises ScenarioError with the CLI's message; a crashing worker raises RunError
and keeps its rows; Ctrl-C stops a run, keeps its rows and raises Interrupted."""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
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
    with pytest.raises(syncroad.ScenarioError, match="--krauss-sigma"):
        # A SUMO option on a native scenario is refused, as by `syncroad run`.
        syncroad.run("scenarios/ring-theorem1.json", krauss_sigma=0.5)
    # A time limit holds a native run too (its Python controller steps in a process of its own).
    assert syncroad.run("scenarios/ring-theorem1.json", timeout_s=600, plots=False).complete
    assert syncroad.run("scenarios/ring-theorem1.json", backend="native", timeout_s=600, plots=False).complete


def test_wrong_types_and_values_are_scenario_errors_in_python_terms(tmp_path):
    # Each of these reached the CLI's argument parser (its usage text, in terms of its flags)
    # or raised a bare Python exception.
    cases = [
        (lambda: syncroad.run("scenarios/ring-theorem1.json", record_every=-1), r"^record_every = -1: must be an integer ≥ 1"),
        (lambda: syncroad.run("scenarios/ring-theorem1.json", record_every=2.5), r"^record_every = 2\.5: must be an integer"),
        (lambda: syncroad.run("scenarios/ring-theorem1.json", tolerance_mps="0.1"), r"^tolerance_mps = '0\.1': must be a number"),
        (lambda: syncroad.run("scenarios/ring-theorem1.json", window_s=float("nan")), r"^window_s = nan"),
        (lambda: syncroad.compare("scenarios/ring-theorem1.json", jobs=0), r"^jobs = 0: must be an integer ≥ 1"),
        (lambda: syncroad.sweep({"base": "x.json"}, tmp_path / "sw", jobs=True), r"^jobs = True: must be an integer"),
        (
            lambda: syncroad.run("scenarios/ring-theorem1.json", backend="native", krauss_sigma=0.5),
            r"^krauss_sigma applies to SUMO runs only",
        ),
        (lambda: syncroad.Scenario.from_dict("x"), r"^Scenario\.from_dict takes the scenario as a dict"),
        (lambda: syncroad.Scenario.from_dict({"name": object()}), r"JSON values only"),
    ]
    for call, message in cases:
        with pytest.raises(syncroad.ScenarioError, match=message) as e:
            call()
        assert "Usage" not in str(e.value) and "tip:" not in str(e.value)
        assert e.value.exit_code == 2
    # NumPy's numbers (a value read from a DataFrame) are numbers.
    import numpy as np

    r = syncroad.run("scenarios/ring-theorem1.json", record_every=np.int64(5), window_s=np.float32(1.0), plots=False)
    times = sorted(set(r.trajectories.column("time_s").to_pylist()))
    assert times[1] - times[0] == pytest.approx(5 * syncroad.Scenario.load("scenarios/ring-theorem1.json").data["step_s"])


def test_a_record_that_cannot_be_read_is_a_record_error_and_a_kept_one_opens(tmp_path):
    run = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "run", plots=False)
    record = json.loads((run.out / "metrics.json").read_text())
    # Kept under another name (as the CLI does when metrics.json cannot be written): the
    # folder and the file itself both open it.
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "metrics.unsaved-abc123.json").write_text(json.dumps(record))
    for where in (kept, kept / "metrics.unsaved-abc123.json"):
        assert syncroad.Run(where).metrics["sync"] == record["sync"]
    # Corrupt, or JSON that is not a run record.
    for text in ("{not json", "[1, 2]"):
        (run.out / "metrics.json").write_text(text)
        with pytest.raises(syncroad.RecordError, match="metrics.json: not a") as e:
            syncroad.Run(run.out).metrics
        assert isinstance(e.value, syncroad.ScenarioError)
        assert e.value.path == run.out / "metrics.json"


def test_a_second_thread_on_the_same_folder_is_refused_and_the_first_keeps_its_run(tmp_path, monkeypatch):
    # Thread A's call holds the folder from before its command starts until its record is
    # read; B's call on the same folder in between (here: while A's command is held at its
    # start) is refused, and A's run is whole. Before, B cleared A's files and A raised
    # FileNotFoundError reading its own metrics.json.
    import threading

    from syncroad import _api

    real = _api._execute
    inside, release = threading.Event(), threading.Event()

    def held(argv, out=None, **kw):
        if threading.current_thread().name == "A":
            inside.set()
            assert release.wait(60)
        return real(argv, out, **kw)

    monkeypatch.setattr(_api, "_execute", held)
    out = tmp_path / "same"
    result = {}

    def a():
        try:
            result["a"] = syncroad.run("scenarios/ring-theorem1.json", out=out, plots=False)
        except Exception as e:  # reported below
            result["a"] = e

    t = threading.Thread(target=a, name="A")
    t.start()
    assert inside.wait(60)
    with pytest.raises(syncroad.ScenarioError, match=r"^out = .*same: another call of this process \(pid \d+\) is writing this folder"):
        syncroad.run("scenarios/ring-theorem1.json", out=out, plots=False)
    release.set()
    t.join()
    assert isinstance(result["a"], syncroad.Run), result["a"]
    assert result["a"].metrics["sync"]["verdict"] == json.loads((out / "metrics.json").read_text())["sync"]["verdict"]
    # Free again once A is done.
    assert syncroad.run("scenarios/ring-theorem1.json", out=out, plots=False).out == out


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


def samples_in(line):
    """The samples a progress line (``run: t = … s (…%), N samples recorded; …``) reports."""
    m = re.search(r"(\d+) samples recorded", line)
    return int(m.group(1)) if m else None


def wait_for_samples(child, samples, seen):
    """Reads the child's stderr until a progress line reports at least ``samples`` recorded:
    the test acts on what the run has done, never after a guessed delay."""
    for line in child.stderr:
        seen.append(line)
        n = samples_in(line)
        if n is not None and n >= samples:
            return n
    raise AssertionError("the run ended without reporting its samples:\n" + "".join(seen))


def start_child(code, args, sigint=signal.SIG_DFL):
    """A Python child running ``code`` in the repository, with SIGINT at ``sigint`` whatever
    this process inherited (a suite started as a background job inherits it ignored)."""
    return subprocess.Popen(
        [sys.executable, "-c", code, *args],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, sigint),
    )


CRASH = """
import json, sys, syncroad
sc = syncroad.Scenario.from_dict(json.loads(sys.argv[1]), base_dir=sys.argv[2])
try:
    syncroad.run(sc, out=sys.argv[3], record_every=10, plots=False, progress="lines")
    print(json.dumps({"raised": False}))
except syncroad.RunError as e:
    partial = e.run
    after = syncroad.run("scenarios/ring-theorem1.json", out=sys.argv[3] + "-after")
    print(json.dumps({"raised": True, "message": str(e), "exit_code": e.exit_code, "out": str(e.out),
                      "partial": partial is not None, "complete": partial.complete,
                      "error": partial.metrics.error, "verdict": partial.verdict,
                      "rows": partial.trajectories.num_rows, "after": after.verdict}))
"""


def test_a_crashing_worker_raises_and_keeps_its_rows(tmp_path):
    sc = scenario("scenarios/sugiyama-ring.json")
    sc["horizon_s"] = 100000
    out = tmp_path / "out"
    child = start_child(CRASH, [json.dumps(sc), str(REPO / "scenarios"), str(out)])
    seen = []
    reported = wait_for_samples(child, 10, seen)
    workers = workers_of(child.pid)
    assert len(workers) == 1, "one worker process, a child of the API's process"
    os.kill(workers[0], signal.SIGSEGV)
    stdout, stderr = child.communicate(timeout=120)
    assert child.returncode == 0, "".join(seen) + stderr
    got = json.loads(stdout.strip().splitlines()[-1])
    assert got["raised"] and "SIGSEGV" in got["message"], got
    assert got["exit_code"] == 3 and got["out"] == str(out)
    assert got["partial"] and got["complete"] is False
    assert "SIGSEGV" in got["error"]
    assert got["verdict"] != "synchronized"
    rows = got["rows"]
    assert rows >= 22 * reported and rows % 22 == 0
    # The API goes on: the next run works.
    assert got["after"] == "synchronized"


CTRL_C = """
import json, sys, syncroad
sc = syncroad.Scenario.from_dict(json.loads(sys.argv[1]), base_dir=sys.argv[2])
try:
    run = syncroad.run(sc, out=sys.argv[3], record_every=10, plots=False, progress="lines")
    print(json.dumps({"interrupted": False, "complete": run.complete}))
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
    # SIGINT at its default, as in an interactive session.
    child = start_child(CTRL_C, [json.dumps(sc), str(REPO / "scenarios"), str(out)])
    seen = []
    reported = wait_for_samples(child, 10, seen)
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=120)
    assert child.returncode == 0, "".join(seen) + stderr
    got = json.loads(stdout.strip().splitlines()[-1])
    assert got["interrupted"] and got["is_keyboard_interrupt"], got
    assert got["complete"] is False and "interrupted" in got["error"]
    assert got["rows"] >= 22 * reported
    assert got["after"] == "synchronized"  # the flag was cleared for the next command


def test_a_process_that_ignores_ctrl_c_runs_on_as_python_does(tmp_path):
    # Started with SIGINT ignored (nohup, `cmd &` in a script): the run goes on to its horizon.
    sc = scenario("scenarios/sugiyama-ring.json")
    sc["horizon_s"] = 3000
    out = tmp_path / "out"
    child = start_child(CTRL_C, [json.dumps(sc), str(REPO / "scenarios"), str(out)], sigint=signal.SIG_IGN)
    seen = []
    wait_for_samples(child, 10, seen)
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=300)
    assert child.returncode == 0, "".join(seen) + stderr
    got = json.loads(stdout.strip().splitlines()[-1])
    assert got == {"interrupted": False, "complete": True}, got
