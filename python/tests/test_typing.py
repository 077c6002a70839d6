"""The package's annotations and the extension's stubs (_syncroad.pyi) type-check strictly:
a signature of the extension that changes without its stub, or an annotation that lies,
fails here. The package sources are checked (python/syncroad), as the wheel ships them."""

import subprocess
import sys

from conftest import REPO


def test_the_package_type_checks_strictly():
    p = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--ignore-missing-imports", "--no-incremental", "syncroad"],
        cwd=REPO / "python", capture_output=True, text=True,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    assert "no issues found in 13 source files" in p.stdout


def test_the_extensions_stub_matches_the_extension():
    # stubtest imports the installed extension and compares each function's signature (pyo3's
    # text signatures) with _syncroad.pyi.
    p = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "syncroad._syncroad"], cwd="/", capture_output=True, text=True,
    )
    assert p.returncode == 0, p.stdout + p.stderr
