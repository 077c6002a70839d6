"""The console script behaves like the cargo-built binary; the wheel installs into a fresh
virtualenv with no Rust toolchain on PATH and runs the one-liner of the guide."""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from conftest import REPO, cli, plain

SCRIPT = Path(sysconfig.get_path("scripts")) / "syncroad"


def script(*args, env=None):
    return subprocess.run([str(SCRIPT), *map(str, args)], cwd=REPO, capture_output=True, text=True, env=env)


@pytest.mark.parametrize(
    "args",
    [
        ["check", "scenarios/sugiyama-ring.json"],  # 0: certified
        ["check", "scenarios/ring-unstable.json"],  # 1: not certified
        ["stability", "scenarios/ring-unstable.json", "--json"],
        ["ifp", "--eta", "1", "--rho", "0.5"],
        ["schema"],
        ["check", "scenarios/no-such-file.json"],  # 2: bad input
        ["run"],  # 2: clap's usage error
        ["frobnicate"],
        ["--help"],  # 0
    ],
)
def test_the_console_script_is_the_binary(args):
    mine, theirs = script(*args), cli(*args)
    assert mine.returncode == theirs.returncode, mine.stderr
    assert mine.stdout == theirs.stdout
    assert mine.stderr == theirs.stderr


def test_the_console_script_runs_sumo_in_its_own_workers(tmp_path):
    mine = script("run", "scenarios/sugiyama-ring.json", "--out", tmp_path / "a", "--no-plots")
    theirs = cli("run", "scenarios/sugiyama-ring.json", "--out", tmp_path / "b", "--no-plots")
    assert mine.returncode == theirs.returncode == 0, mine.stderr
    assert (tmp_path / "a/metrics.json").read_text() == (tmp_path / "b/metrics.json").read_text()
    assert plain(mine.stdout, tmp_path / "a") == plain(theirs.stdout, tmp_path / "b")
    # Its worker imported libsumo from the package's environment.
    assert f"(libsumo {sys.prefix}/" in mine.stdout, mine.stdout


def wheel():
    named = os.environ.get("SYNCROAD_WHEEL")
    if named:
        return Path(named)
    found = sorted((REPO / "target" / "wheels").glob("syncroad-*.whl"), key=lambda p: p.stat().st_mtime)
    assert found, "no wheel in target/wheels: build it with `maturin build --release -o target/wheels`"
    return found[-1]


ONE_LINER = "import syncroad; r = syncroad.run('scenarios/sugiyama-ring.json'); print(r.verdict, r.trajectories.num_rows)"


def test_the_wheel_installs_and_runs_without_a_rust_toolchain(tmp_path):
    venv = tmp_path / "fresh"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    # A PATH without cargo, rustc or maturin: only the fresh venv and the system.
    path = os.pathsep.join([str(venv / "bin"), "/usr/local/bin", "/usr/bin", "/bin"])
    for tool in ("cargo", "rustc", "maturin"):
        assert shutil.which(tool, path=path) is None, f"{tool} is on the test's PATH"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CARGO", "RUST", "VIRTUAL_ENV", "PYTHON", "SYNCROAD"))}
    env.update(PATH=path, HOME=os.environ.get("HOME", str(tmp_path)))
    # Without byte-compiling the dependencies' modules (a third of the install's time; a
    # failure there is only a warning to pip): Python compiles what it imports.
    pip = subprocess.run(
        [str(venv / "bin/python"), "-m", "pip", "install", "--disable-pip-version-check", "-q", "--no-compile", str(wheel())],
        env=env, capture_output=True, text=True,
    )
    assert pip.returncode == 0, pip.stderr
    p = subprocess.run([str(venv / "bin/python"), "-c", ONE_LINER], cwd=REPO, env=env, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    verdict, rows = p.stdout.split()
    theirs = cli("run", "scenarios/sugiyama-ring.json", "--out", tmp_path / "cli", "--no-plots")
    assert f"verdict: {verdict}" in theirs.stdout, theirs.stdout
    with open(tmp_path / "cli/trajectories.csv") as f:
        assert int(rows) == sum(1 for _ in f) - 1
    # The fresh venv's SUMO ran it (its own libsumo, not the project's .venv), and its
    # console script is on its PATH.
    where = subprocess.run(
        [str(venv / "bin/python"), "-c", "import libsumo; print(libsumo.__file__)"], env=env, capture_output=True, text=True
    )
    assert where.stdout.startswith(str(venv)), where.stdout
    code = subprocess.run(["syncroad", "check", "scenarios/ring-unstable.json"], cwd=REPO, env=env, capture_output=True)
    assert code.returncode == cli("check", "scenarios/ring-unstable.json").returncode == 1


def test_slurm_job_scripts_run_the_console_script(tmp_path):
    spec = tmp_path / "spec.json"
    spec.write_text((REPO / "sweeps/ring-gain-delay.native.json").read_text().replace("../scenarios", str(REPO / "scenarios")))
    p = script("sweep", spec, "--out", tmp_path / "out", "--emit-slurm", tmp_path / "jobs", "--shards", "2")
    assert p.returncode == 0, p.stderr
    job = (tmp_path / "jobs/sweep.sbatch").read_text()
    # Not the interpreter the console script runs in: the command itself.
    assert f"exec {SCRIPT} sweep " in job, job


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_the_console_script_stops_on_a_signal_as_the_binary_does(tmp_path, sig, code):
    sc = json.loads((REPO / "scenarios/sugiyama-ring.json").read_text())
    sc["horizon_s"] = 100000
    sc["sumo"]["net"] = str(REPO / "sumo-nets/sugiyama-ring.net.xml")
    path = tmp_path / "long.json"
    path.write_text(json.dumps(sc))
    out = tmp_path / "out"
    # Started as from a background job (SIGINT ignored): the CLI handles its signals itself.
    child = subprocess.Popen(
        [str(SCRIPT), "run", str(path), "--out", str(out), "--no-plots", "--record-every", "10",
         "--progress", "lines"],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    # Once the run reports recorded samples, whatever the machine's load.
    seen = []
    for line in child.stderr:
        seen.append(line)
        m = re.search(r"(\d+) samples recorded", line)
        if m and int(m.group(1)) >= 10:
            reported = int(m.group(1))
            break
    else:
        raise AssertionError("no progress line:\n" + "".join(seen))
    child.send_signal(sig)
    _, rest = child.communicate(timeout=120)
    stderr = "".join(seen) + rest
    assert child.returncode == code, stderr
    assert "Traceback" not in stderr, stderr  # the CLI's message, not Python's
    m = json.loads((out / "metrics.json").read_text())
    assert m["complete"] is False and "interrupted" in m["error"]
    with open(out / "trajectories.csv") as f:
        assert sum(1 for _ in f) - 1 >= 22 * reported
