"""The Python side of a user's controller (loaded by syncroad's Rust adapter, `user_law.rs`).

`build` imports the class and makes the instance; a `Stepper` owns the observation's arrays
(one float64 block the adapter writes each step before calling `Stepper.step`) and the
commands' array (which the adapter reads after it), so a step allocates nothing here.
Everything raises ordinary exceptions whose messages name what was wrong; the adapter adds
the traceback.
"""

import importlib
import importlib.util
import io
import os
import pickle
import sys

import numpy as np

# Rows of the packed buffer, in order.
ROWS = ("speed_mps", "accel_mps2", "odometer_m", "gap_m", "leader_speed_mps")


class Observation:
    """The vehicles at one step; arrays are read-only and indexed like `ids`.

    time_s            simulated time [s]
    step              step index n (the commands are the speeds wanted at step n + 1)
    dt_s              step length [s]
    ids               vehicle ids (tuple of str)
    The arrays are views refreshed in place every step: copy one (`.copy()`) to keep it.

    speed_mps         speeds [m/s]
    accel_mps2        accelerations over the last step [m/s^2] (0 at the first step)
    odometer_m        distance driven since the start [m]
    gap_m             bumper-to-bumper gap to the vehicle ahead [m] (inf: nobody ahead)
    leader_speed_mps  that vehicle's speed [m/s] (nan: nobody ahead)
    controlled        True where the controller's command is applied (others: humans, SUMO)
    length_m          vehicle lengths [m]
    ring_length_m     circumference of a ring road [m], None on an open road
    speed_limit_mps   the road's speed limit [m/s] (in SUMO the lowest lane limit along the
                      road; inf where the road has none, as on the native simulator)
    signal_distance_m distance to the next traffic light ahead on the vehicle's route [m]
                      (inf: none, or a road without traffic lights)
    signal_stop       1.0 where that light shows red or yellow (the vehicle must stop before
                      it if it can), else 0.0
    """

    __slots__ = (
        "time_s",
        "step",
        "dt_s",
        "ids",
        "speed_mps",
        "accel_mps2",
        "odometer_m",
        "gap_m",
        "leader_speed_mps",
        "controlled",
        "length_m",
        "ring_length_m",
        "speed_limit_mps",
        "signal_distance_m",
        "signal_stop",
    )

    def __repr__(self):
        return (
            f"Observation(t={self.time_s:.3f} s, step={self.step}, vehicles={len(self.ids)}, "
            f"mean speed={float(np.mean(self.speed_mps)):.3f} m/s)"
        )


def _load_module(kind, where):
    if kind == "module":
        return importlib.import_module(where)
    path = os.path.abspath(where)
    folder = os.path.dirname(path)
    # The file may import modules beside it, as it would when run as a script; but its
    # folder comes last, so that a file there never stands in for an installed module (a
    # libsumo.py, a numpy.py, syncroad's own): those are found where they are installed.
    if folder not in sys.path:
        sys.path.append(folder)
    stem = os.path.splitext(os.path.basename(path))[0]
    name = "syncroad_user_" + "".join(c if c.isalnum() else "_" for c in stem)
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path} as a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _resolve(module, dotted):
    obj = module
    for part in dotted.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            names = sorted(n for n in dir(module) if not n.startswith("_") and isinstance(getattr(module, n), type))
            raise AttributeError(
                f"{module.__name__} ({getattr(module, '__file__', '?')}) has no class {dotted}; "
                f"its classes: {', '.join(names) or 'none'}"
            ) from None
    return obj


class _Unpickler(pickle.Unpickler):
    """Finds the controller's class in the module loaded from its file when the module it was
    pickled from (a script's __main__, say) is not importable here."""

    def __init__(self, data, module):
        super().__init__(io.BytesIO(data))
        self._module = module

    def find_class(self, module, name):
        try:
            return super().find_class(module, name)
        except (ImportError, AttributeError):
            return _resolve(self._module, name)


def build(kind, where, class_name, params, state_path):
    """The controller instance and its command kind ('speed' or 'acceleration')."""
    module = _load_module(kind, where)
    cls = _resolve(module, class_name)
    if not callable(cls):
        raise TypeError(f"{class_name} in {module.__name__} is not a class")
    if state_path is not None:
        with open(state_path, "rb") as f:
            obj = _Unpickler(f.read(), module).load()
    else:
        obj = cls(**params)
    step = getattr(obj, "step", None)
    if not callable(step):
        raise TypeError(
            f"{class_name} has no step method; a controller defines step(self, obs) returning "
            "one target speed per vehicle"
        )
    command = getattr(obj, "command", "speed")
    if command not in ("speed", "acceleration"):
        raise ValueError(
            f"{class_name}.command = {command!r}; valid: 'speed' (step returns target speeds "
            "[m/s], the default) or 'acceleration' (step returns accelerations [m/s^2])"
        )
    return obj, command


class Stepper:
    """Calls `obj.step(obs)` each step; the adapter fills `rows` before and reads `out` after
    (their addresses are `rows_address` and `out_address`)."""

    def __init__(
        self, obj, ids, dt_s, length_m, ring_length_m, controlled, speed_limit_mps=None, signals=False
    ):
        self.controller = obj
        self.step_fn = obj.step
        self.n = len(ids)
        self.rows = np.zeros((len(ROWS), self.n), dtype=np.float64)
        self.out = np.zeros(self.n, dtype=np.float64)
        self.rows_address = self.rows.__array_interface__["data"][0]
        self.out_address = self.out.__array_interface__["data"][0]
        obs = Observation()
        # Read-only views of the rows, refreshed in place every step.
        for name, row in zip(ROWS, self.rows):
            row.flags.writeable = False
            setattr(obs, name, row)
        obs.ids = tuple(ids)
        obs.dt_s = dt_s
        obs.length_m = np.array(length_m, dtype=np.float64)
        obs.length_m.flags.writeable = False
        obs.ring_length_m = ring_length_m
        obs.controlled = np.array(controlled, dtype=bool)
        obs.controlled.flags.writeable = False
        obs.speed_limit_mps = float("inf") if speed_limit_mps is None else float(speed_limit_mps)
        self.signal_distance = np.full(self.n, np.inf)
        self.signal_stop = np.zeros(self.n)
        obs.signal_distance_m = self.signal_distance[:]
        obs.signal_distance_m.flags.writeable = False
        obs.signal_stop = self.signal_stop[:]
        obs.signal_stop.flags.writeable = False
        self.signal_distance_address = self.signal_distance.__array_interface__["data"][0]
        self.signal_stop_address = self.signal_stop.__array_interface__["data"][0]
        # In a SUMO worker on a network with traffic lights: the loop's libsumo, imported at
        # the first step (the controller is built before the loop starts SUMO).
        self.signals = signals
        self.next_tls = None
        self.ids = tuple(ids)
        self.obs = obs

    def read_signals(self):
        """The traffic lights ahead of every vehicle into `signal_distance`, `signal_stop`."""
        if self.next_tls is None:
            self.next_tls = importlib.import_module("libsumo").vehicle.getNextTLS
        for i, vid in enumerate(self.ids):
            ahead = self.next_tls(vid)
            if ahead:
                _, _, distance, state = ahead[0]
                self.signal_distance[i] = distance
                self.signal_stop[i] = 1.0 if state in "rRyYu" else 0.0
            else:
                self.signal_distance[i] = np.inf
                self.signal_stop[i] = 0.0

    def step(self, time_s, step):
        obs = self.obs
        obs.time_s = time_s
        obs.step = step
        if self.signals:
            self.read_signals()
        out = self.step_fn(obs)
        try:
            a = np.asarray(out)
        except (TypeError, ValueError) as e:
            raise TypeError(
                f"step returned {type(out).__name__} ({e}); return a numpy array or a sequence "
                f"of {self.n} numbers, one per vehicle of obs.ids"
            ) from None
        # Real numbers only: numpy would read "5" as 5.0, True as 1.0 and drop the imaginary
        # part of a complex number, and a controller's mistake would drive as a speed.
        if a.dtype.kind not in "iuf":
            kind = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "bytes"}.get(
                a.dtype.kind, f"values of type {a.dtype}"
            )
            if a.dtype.kind == "O":
                odd = next((x for x in a.ravel() if not isinstance(x, (int, float, np.integer, np.floating)) or isinstance(x, bool)), None)
                kind = f"a {type(odd).__name__} ({odd!r:.40})" if odd is not None else kind
            raise TypeError(
                f"step returned {kind} where speeds go; return {self.n} real numbers (int or "
                "float), one per vehicle of obs.ids"
            )
        a = a.astype(np.float64, copy=False)
        if a.shape != (self.n,):
            raise ValueError(
                f"step returned {a.size} value(s) of shape {a.shape}; {self.n} are needed, one "
                "per vehicle of obs.ids"
            )
        self.out[...] = a
