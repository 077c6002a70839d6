"""The exceptions of the syncroad API, one per way a command of the CLI ends badly."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

# ``run`` below is a syncroad.Run; typed Any so that this module, which every other imports,
# imports none of them (no import circle).
_Run = Any


class SyncroadError(Exception):
    """Base class of syncroad's errors. ``exit_code`` is the CLI's for the same failure."""

    exit_code: int = 3


class ScenarioError(SyncroadError, ValueError):
    """Bad input (the CLI's exit code 2): the message is the CLI's, naming the field, the
    value and what would be valid. Nothing ran."""

    exit_code = 2


class RecordError(ScenarioError):
    """A run's record could not be read: ``metrics.json`` (or a kept
    ``metrics.unsaved-*.json``) is not valid JSON or is not syncroad's. ``path`` is the file."""

    def __init__(self, message: str, path: Optional[Path] = None):
        super().__init__(message)
        self.path = path


class RunError(SyncroadError, RuntimeError):
    """A run failed while executing (the CLI's exit code 3): SUMO crashed, timed out, or a
    file could not be written. ``run`` holds the rows received before the failure (the run's
    folder, marked incomplete), or is ``None`` when nothing ran."""

    exit_code = 3

    def __init__(self, message: str, out: Optional[Path] = None, run: Optional[_Run] = None):
        super().__init__(message)
        self.out = out
        self.run = run


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (``KeyboardInterrupt``) stopped a command, as Ctrl-C stops the CLI: every row
    already computed is written in ``out`` (a sweep resumes from there when run again).
    ``run`` is the interrupted run of :func:`syncroad.run`, when it wrote its record."""

    exit_code = 130

    def __init__(self, out: Optional[Path], run: Optional[_Run] = None):
        super().__init__(f"interrupted; the rows computed so far are in {out}")
        self.out = out
        self.run = run
