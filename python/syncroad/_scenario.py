"""Scenarios: a JSON file (or a dict) validated by the CLI's own loader."""

from __future__ import annotations

import json
import os
import tempfile
import weakref
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Tuple, Union

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


def _absolute_controller(controller: Mapping[str, Any], base_dir: Path) -> Dict[str, Any]:
    """A ``controller`` block with its file (``FILE.py:Class``, not ``module:Class``) and
    pickled ``state`` resolved against ``base_dir``."""
    c = dict(controller)
    python = c.get("python")
    if isinstance(python, str) and ":" in python:
        where, cls_name = python.rsplit(":", 1)
        if where.endswith(".py") or "/" in where:
            c["python"] = f"{_absolute(where, base_dir)}:{cls_name}"
    if isinstance(c.get("state"), str):
        c["state"] = _absolute(c["state"], base_dir)
    return c


class Scenario:
    """A validated scenario (the CLI's JSON format, see the guide's Scenarios chapter).

    ``path`` is the file every command is given; ``data`` the parsed JSON (a copy: change it
    and call :meth:`from_dict` to get a new validated scenario).
    """

    path: Path
    data: Dict[str, Any]
    _controller_state: Any = None

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
        the ``sumo`` section (``net``, ``config``, ``routes``, ``additional``) and of the
        ``controller`` (its ``FILE.py`` and ``state``) resolve against ``base_dir`` (default:
        the current folder). Raises :class:`ScenarioError` with the CLI's message."""
        if not isinstance(data, Mapping):
            raise ScenarioError(
                f"Scenario.from_dict takes the scenario as a dict (the JSON file's content), "
                f"got {type(data).__name__} {str(data)[:60]!r}"
            )
        try:
            d = json.loads(json.dumps(data))  # a deep copy that is also checked to be JSON
        except (TypeError, ValueError) as e:
            raise ScenarioError(f"Scenario.from_dict: the scenario must hold JSON values only ({e})") from None
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
        if isinstance(d.get("controller"), dict):
            d["controller"] = _absolute_controller(d["controller"], base)
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

    def with_controller(self, controller: Any) -> "Scenario":
        """The same scenario driven by ``controller``: a ``controller`` block (``{"python":
        "FILE.py:Class", "params": {...}}``) or an object with a ``step(obs)`` method, which
        is pickled (its class is loaded from the file that defines it, in the SUMO worker or
        the native simulator, and the pickle restores its state)."""
        d = dict(self.data)
        if isinstance(controller, Mapping):
            # The block's files are the caller's (relative to the current folder); the rest of
            # the scenario's are its file's.
            d["controller"] = _absolute_controller(controller, Path.cwd())
            return Scenario.from_dict(d, base_dir=self.path.parent)
        block, state = _pickled_controller(controller)
        d["controller"] = block
        sc = Scenario.from_dict(d, base_dir=self.path.parent)
        # The pickled state lives as long as the scenario that names it.
        sc._controller_state = state
        return sc

    def __repr__(self) -> str:
        return f"Scenario({self.name!r}, backend={self.backend!r}, path={str(self.path)!r})"


def _pickled_controller(controller: Any) -> "Tuple[Dict[str, Any], tempfile.TemporaryDirectory[str]]":
    """The ``controller`` block of an object (its class's file and name, and its pickled
    state) and the temporary folder that holds the state (removed when it is collected)."""
    import inspect
    import pickle

    cls = type(controller)
    name = cls.__qualname__
    if not callable(getattr(controller, "step", None)):
        raise ScenarioError(
            f"controller = {cls.__name__} object: it has no step method; a controller defines "
            "step(self, obs) returning one target speed per vehicle"
        )
    try:
        source = inspect.getsourcefile(cls)
    except TypeError:
        source = None
    if source is None or not Path(source).is_file() or "<locals>" in name:
        raise ScenarioError(
            f"controller = {name} object: its class is not defined at the top of a .py file "
            f"(it comes from {source or cls.__module__}); SUMO runs it in a worker process, which "
            "loads the class from its file: move the class into a .py file and import it"
        )
    try:
        state = pickle.dumps(controller)
    except Exception as e:  # pickle raises many types; the message is what helps
        raise ScenarioError(
            f"controller = {name} object: it cannot be pickled ({type(e).__name__}: {e}); give "
            'its class and parameters instead: {"python": "FILE.py:Class", "params": {...}}'
        ) from None
    tmp = tempfile.TemporaryDirectory(prefix="syncroad-controller-")
    path = Path(tmp.name) / "controller.pickle"
    path.write_bytes(state)
    return {"python": f"{Path(source).resolve()}:{name}", "state": str(path)}, tmp


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
