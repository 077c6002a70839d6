"""Scenarios: a JSON file (or a dict) validated by the CLI's own loader."""

from __future__ import annotations

import json
import os
import tempfile
import weakref
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Union

from syncroad import _syncroad
from syncroad._errors import ScenarioError

PathLike = Union[str, "os.PathLike[str]"]


def _write_temporary(owner: object, data: Mapping[str, Any], name: str) -> Path:
    """Writes ``data`` as ``name`` in a fresh temporary folder removed with ``owner``."""
    tmp = tempfile.TemporaryDirectory(prefix="syncroad-")
    weakref.finalize(owner, tmp.cleanup)
    path = Path(tmp.name) / name
    path.write_text(json.dumps(data, indent=2) + "\n")
    return path


def _absolute(value: str, base_dir: Path) -> str:
    p = Path(value)
    return str(p if p.is_absolute() else (base_dir / p).resolve())


class Scenario:
    """A validated scenario (the CLI's JSON format, see the guide's Scenarios chapter).

    ``path`` is the file every command is given; ``data`` the parsed JSON (a copy: change it
    and call :meth:`from_dict` to get a new validated scenario).
    """

    path: Path
    data: Dict[str, Any]

    def __init__(self, path: Path, data: Dict[str, Any]):
        self.path = path
        self.data = data

    @classmethod
    def load(cls, path: PathLike) -> "Scenario":
        """Reads and validates a scenario file; relative paths inside it (``sumo.net``,
        ``sumo.config``, ``sumo.routes``, ``sumo.additional``) resolve against its folder. Raises :class:`ScenarioError` with the CLI's message."""
        p = Path(path)
        error = _syncroad.validate_scenario(str(p))
        if error is not None:
            raise ScenarioError(error)
        return cls(p, json.loads(p.read_text()))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: Optional[PathLike] = None) -> "Scenario":
        """Validates a scenario given as a dict (the JSON file's content). Relative files of
        the ``sumo`` section (``net``, ``config``, ``routes``, ``additional``) resolve against
        ``base_dir`` (default: the current folder). Raises
        :class:`ScenarioError` with the CLI's message."""
        d = json.loads(json.dumps(data))  # a deep copy that is also checked to be JSON
        base = Path(base_dir) if base_dir is not None else Path.cwd()
        sumo = d.get("sumo")
        if isinstance(sumo, dict):
            # Every file the section names: the network, a SUMO configuration, the user's
            # own route and additional files.
            for key in ("net", "config"):
                if isinstance(sumo.get(key), str):
                    sumo[key] = _absolute(sumo[key], base)
            for key in ("routes", "additional"):
                files = sumo.get(key)
                if isinstance(files, list):
                    sumo[key] = [_absolute(f, base) if isinstance(f, str) else f for f in files]
        name = str(d.get("name") or "scenario")
        safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in name)
        sc = cls.__new__(cls)
        path = _write_temporary(sc, d, f"{safe}.json")
        error = _syncroad.validate_scenario(str(path))
        if error is not None:
            raise ScenarioError(error)
        cls.__init__(sc, path, d)
        return sc

    @property
    def name(self) -> str:
        """The scenario's name (``"scenario"`` when it has none)."""
        return str(self.data.get("name") or "scenario")

    @property
    def backend(self) -> str:
        """``"native"`` or ``"sumo"``."""
        return str(self.data.get("backend", "native"))

    def with_backend(self, backend: str) -> "Scenario":
        """The same scenario on another backend (``"native"`` or ``"sumo"``)."""
        if backend == self.backend:
            return self
        d = dict(self.data)
        d["backend"] = backend
        return Scenario.from_dict(d, base_dir=self.path.parent)

    def __repr__(self) -> str:
        return f"Scenario({self.name!r}, backend={self.backend!r}, path={str(self.path)!r})"


ScenarioLike = Union[Scenario, PathLike, Mapping[str, Any]]


def as_scenario(scenario: ScenarioLike) -> Scenario:
    """A :class:`Scenario` from a scenario, a path or a dict."""
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, Mapping):
        return Scenario.from_dict(scenario)
    return Scenario.load(scenario)


def write_spec(folder: PathLike, spec: Mapping[str, Any], base_dir: Optional[PathLike]) -> Path:
    """Writes a sweep spec given as a dict into ``folder``, its relative ``base`` resolved
    against ``base_dir`` (default: the current folder)."""
    d = json.loads(json.dumps(spec))
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    if isinstance(d.get("base"), str):
        d["base"] = _absolute(d["base"], base)
    path = Path(folder) / "sweep.json"
    path.write_text(json.dumps(d, indent=2) + "\n")
    return path
