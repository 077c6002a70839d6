"""A run stepped by the caller: ``with syncroad.Simulation(scenario) as sim: ...``."""

from __future__ import annotations

import os
import threading
from multiprocessing.connection import Listener
from types import SimpleNamespace
from typing import Any, Dict, Optional, Sequence, Union

import numpy as np

from syncroad._errors import RunError, ScenarioError
from syncroad._remote import CLOSED, FIRST_FIELDS, ROWS, Receiver, RemoteController
from syncroad._run import Run
from syncroad._scenario import PathLike, ScenarioLike, as_scenario

#: How long the first observation may take to arrive (SUMO starts in a worker process) [s].
START_TIMEOUT_S = 120.0


class Simulation:
    """A run of ``scenario`` whose vehicles the caller commands step by step::

        with syncroad.Simulation("scenarios/sugiyama-ring.json") as sim:
            while not sim.done:
                obs = sim.observe()
                sim.step(np.minimum(obs.speed_mps + 0.1, 8.0))
        sim.run.metrics.sync.verdict

    It is an ordinary run whose controller is the caller: the scenario's law is replaced on
    the vehicles it drives (humans and SUMO's drivers of a ``mixed`` block drive theirs), the
    SUMO backend steps in its worker process, and the run's files (``metrics.json``,
    trajectories, plots) are written into ``out`` when it closes — marked incomplete if it is
    closed before its horizon. ``observe()`` gives the controller's observation (numpy arrays:
    ``speed_mps``, ``gap_m``, ``leader_speed_mps``, ``ids``, ``controlled``, ...; see the
    guide's "Your own controller"); ``step(speeds)`` sends one target speed per vehicle and
    advances one step. A step without speeds keeps every vehicle's speed.
    """

    def __init__(
        self,
        scenario: ScenarioLike,
        backend: Optional[str] = None,
        out: Optional[PathLike] = None,
        *,
        plots: bool = False,
        timeout_s: Optional[float] = None,
    ) -> None:
        from syncroad._api import run

        sc = as_scenario(scenario)
        authkey = os.urandom(16)
        self._listener = Listener(family="AF_UNIX", authkey=authkey)
        remote = RemoteController(self._listener.address, authkey)
        self.run: Optional[Run] = None
        self.error: Optional[BaseException] = None
        self.done = False
        self._closing = False
        self._conn: Any = None
        self._obs: Optional[SimpleNamespace] = None

        def target() -> None:
            try:
                self.run = run(sc, backend, out, controller=remote, plots=plots,
                               timeout_s=timeout_s, progress="never")
            except RunError as e:
                self.run = e.run
                if not (self._closing and CLOSED in str(e)):
                    self.error = e
            except BaseException as e:  # noqa: BLE001 - handed to the caller's thread
                self.error = e
            finally:
                self.done = True

        self._thread = threading.Thread(target=target, name="syncroad-simulation", daemon=True)
        self._thread.start()
        self._conn = self._accept()
        self._receiver = Receiver(self._conn)
        self._first = True
        self._receive()

    def _accept(self) -> Any:
        """The run's connection, or the run's own error when it ended before connecting."""
        got: Dict[str, Any] = {}

        def accept() -> None:
            try:
                got["conn"] = self._listener.accept()
            except OSError as e:
                got["error"] = e

        t = threading.Thread(target=accept, daemon=True)
        t.start()
        t.join(0.0)
        waited = 0.0
        while t.is_alive() and not self.done and waited < START_TIMEOUT_S:
            t.join(0.05)
            waited += 0.05
        if "conn" in got:
            return got["conn"]
        self._listener.close()
        self._thread.join()
        if self.error is not None:
            raise self.error
        raise RunError(f"the run did not start stepping within {START_TIMEOUT_S:.0f} s")

    def _receive(self) -> None:
        """The next observation, or the end of the run (its horizon)."""
        try:
            if self._first:
                # The constant fields, once.
                obs = SimpleNamespace(**self._conn.recv())
                for key in FIRST_FIELDS:
                    value = getattr(obs, key)
                    if isinstance(value, np.ndarray):
                        value.flags.writeable = False
                self._obs, self._first = obs, False
            packed = self._receiver.recv_bytes()
        except EOFError:
            # The run finished (its horizon) or failed: its thread says which.
            self._finish()
            return
        assert self._obs is not None
        obs = self._obs
        values = np.frombuffer(packed, dtype=np.float64)
        obs.time_s, obs.step = float(values[0]), int(values[1])
        rows = values[2:].reshape(len(ROWS), -1)
        for key, row in zip(ROWS, rows):
            setattr(obs, key, row)

    def _finish(self) -> None:
        self._thread.join()
        self.done = True
        self._conn.close()
        self._listener.close()
        if self.error is not None:
            error, self.error = self.error, None
            raise error

    def observe(self) -> SimpleNamespace:
        """The observation at the current step (read-only arrays, indexed like ``obs.ids``)."""
        if self._obs is None:
            raise RunError("the simulation has no observation")
        return self._obs

    @property
    def time_s(self) -> float:
        """Simulated time of the current observation [s]."""
        return float(self.observe().time_s)

    def step(self, speeds: "Union[Sequence[float], np.ndarray[Any, Any], None]" = None) -> Optional[SimpleNamespace]:
        """Commands ``speeds`` (one target speed per vehicle of ``obs.ids``; ``None`` keeps the
        current speeds) and advances one step; returns the new observation, or ``None`` when
        the run reached its horizon (``done``; the record is then in ``run``)."""
        if self.done:
            raise RunError("the simulation has ended; its record is in sim.run")
        obs = self.observe()
        v = np.array(obs.speed_mps if speeds is None else speeds, dtype=np.float64)
        if v.shape != (len(obs.ids),):
            raise ScenarioError(
                f"speeds: {v.size} value(s) of shape {v.shape}; {len(obs.ids)} are needed, one per vehicle of obs.ids"
            )
        self._conn.send_bytes(v.tobytes())
        self._receive()
        return None if self.done else self._obs

    def close(self) -> Optional[Run]:
        """Ends the run (before its horizon: marked incomplete) and returns its :class:`Run`."""
        if not self.done:
            self._closing = True
            try:
                self._conn.send_bytes(b"")
            except OSError:
                pass
            self._receive()
            while not self.done:
                self._receive()
        return self.run

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "done" if self.done else f"t = {self.time_s:.3f} s"
        return f"Simulation({state})"


__all__ = ["Simulation"]
