"""Shared fixtures of the Python package's tests (run by scripts/test.sh).

The package under test is the installed wheel (``import syncroad``); the CLI it is compared
with is the cargo-built binary (``SYNCROAD_BIN``, default ``target/release/syncroad``)."""

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BIN = Path(os.environ.get("SYNCROAD_BIN", REPO / "target" / "release" / "syncroad"))


def cli(*args, check_code=None, cwd=REPO):
    """Runs the cargo-built ``syncroad`` binary; returns the CompletedProcess."""
    assert BIN.is_file(), f"{BIN}: build the CLI first (cargo build --release)"
    p = subprocess.run([str(BIN), *map(str, args)], cwd=cwd, capture_output=True, text=True)
    if check_code is not None:
        assert p.returncode == check_code, f"exit {p.returncode}\n{p.stdout}\n{p.stderr}"
    return p


def plain(text, out):
    """A run's summary without what differs between two runs of the same scenario: the output
    folder, and where libsumo was loaded from (the package's environment for the package, the
    project's .venv for the cargo-built binary)."""
    return re.sub(r"\(libsumo [^)]*\)", "(libsumo …)", text.replace(str(out), "OUT"))


def read_json(path):
    return json.loads(Path(path).read_text())


@pytest.fixture(autouse=True)
def _in_repo(monkeypatch):
    """Relative scenario paths are the repository's, as in the guide's examples."""
    monkeypatch.chdir(REPO)


def pytest_sessionfinish(session, exitstatus):
    session.config._syncroad_exitstatus = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leaves with pytest's own exit status once everything is reported: pyarrow (which reads
    the sweeps' Parquet tables here) can abort at interpreter shutdown, after the work is done,
    with "terminate called without an active exception" (apache/arrow#34314), which would turn
    a passed run into exit 134."""
    status = getattr(config, "_syncroad_exitstatus", None)
    if status is not None:
        import sys

        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
