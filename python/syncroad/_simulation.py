"""A run stepped by the caller: ``with syncroad.Simulation(scenario) as sim: ...``."""

from __future__ import annotations

import os
import threading
import time
import weakref
from multiprocessing.connection import Listener
from types import SimpleNamespace
from typing import Any, Dict, Optional, Sequence, Union

import numpy as np

from syncroad import _syncroad
from syncroad._errors import RunError, ScenarioError
from syncroad._remote import CLOSED, FIRST_FIELDS, LOCAL, ROWS, Receiver, SimulationController
from syncroad._run import Run
from syncroad._scenario import PathLike, ScenarioLike, as_scenario

#: How long the first observation may take to arrive (SUMO starts first) [s].
START_TIMEOUT_S = 120.0


class Simulation:
    """A run of ``scenario`` whose vehicles the caller commands step by step::

        with syncroad.Simulation("scenarios/sugiyama-ring.json") as sim:
            while not sim.done:
                obs = sim.observe()
                sim.step(np.minimum(obs.speed_mps + 0.1, 8.0))
        sim.run.metrics.sync.verdict

    It is an ordinary run whose controller is the caller: the scenario's law is replaced on
    the vehicles it drives (humans and SUMO's drivers of a ``mixed`` block drive theirs), and
    the run's files (``metrics.json``, trajectories, plots) are written into ``out`` when it
    closes — marked incomplete if it is closed before its horizon.

    SUMO steps in this process (``in_process=True``, the default: this process's libsumo on a
    thread of its own, the observation and the commands handed over in memory), as the field's
    environments run libsumo; ``sim.in_process`` says whether it does. libsumo runs one
    simulation per process, so while another Simulation of this process (or this process's own
    code) has libsumo, and with ``in_process=False`` or a ``timeout_s``, the run steps in a
    worker process instead, over a local connection: the same run, a few times slower per
    step, and a SUMO that crashes takes only its worker down. ``observe()`` gives the controller's observation (numpy arrays:
    ``speed_mps``, ``gap_m``, ``leader_speed_mps``, ``ids``, ``controlled``, ...; see the
    guide's "Your own controller"); ``step(speeds)`` sends one target speed per vehicle and
    advances one step, as ``command(speeds)`` then ``step()`` does. A step without speeds or
    a command keeps every vehicle's speed.
    """

    def __init__(
        self,
        scenario: ScenarioLike,
        backend: Optional[str] = None,
        out: Optional[PathLike] = None,
        *,
        plots: bool = False,
        timeout_s: Optional[float] = None,
        in_process: bool = True,
    ) -> None:
        from syncroad._api import run

        sc = as_scenario(scenario)
        # What the run's thread reports. The thread holds this, not the Simulation, so that a
        # Simulation dropped without close() is collected, and its run closed (below).
        state = self._state = _RunState()
        self._conn: Any = None
        self._listener: Any = None
        self._handoff: Any = None
        self._obs: Optional[SimpleNamespace] = None
        self._pending = False
        self._commanded: "Optional[np.ndarray[Any, Any]]" = None
        # This process steps the run (its libsumo, if no other run of it holds it) unless a
        # time limit is asked for, which only a worker process can be held to.
        # (``run`` steps SUMO unless asked for the native simulator.)
        native = backend == "native"
        claimed = in_process and timeout_s is None and not native and _syncroad.claim_libsumo()
        #: True when the run steps in this process (no worker process, no socket).
        self.in_process = in_process and timeout_s is None and (native or claimed)
        if self.in_process:
            self._handoff = _syncroad.Handoff()
            token = os.urandom(16).hex()
            LOCAL[token] = self._handoff
            self._token: Optional[str] = token
            controller = SimulationController(token=token)
        else:
            self._token = None
            authkey = os.urandom(16)
            self._listener = Listener(family="AF_UNIX", authkey=authkey)
            controller = SimulationController(self._listener.address, authkey)

        def target() -> None:
            try:
                state.run = run(sc, backend, out, controller=controller, plots=plots,
                                timeout_s=timeout_s, progress="never", _here=claimed)
            except RunError as e:
                state.run = e.run
                if not (state.closing and CLOSED in str(e)):
                    state.error = e
            except BaseException as e:  # noqa: BLE001 - handed to the caller's thread
                state.error = e
            finally:
                if claimed:
                    _syncroad.release_libsumo()
                state.done = True

        self._thread = threading.Thread(target=target, name="syncroad-simulation", daemon=True)
        self._thread.start()
        if self.in_process:
            self._first = False
            self._start_here()
        else:
            self._conn = self._accept()
            self._receiver = Receiver(self._conn)
            self._first = True
            self._receive()
        # Dropped without close(): the run closes as close() would close it (its record
        # written, marked incomplete), and a claimed libsumo is given back.
        if not self.done:
            closer = weakref.finalize(self, _discarded, state, self._handoff, self._conn)
            closer.atexit = False

    @property
    def run(self) -> Optional[Run]:
        """The run's record, once it has ended (``None`` before)."""
        return self._state.run

    @property
    def error(self) -> Optional[BaseException]:
        """What the run failed with, until it is raised in the caller's thread."""
        return self._state.error

    @property
    def done(self) -> bool:
        """True once the run has ended (its horizon, a close, or a failure)."""
        return self._state.done

    def _start_here(self) -> None:
        """Waits for the run's first observation in this process, or its end. Whatever stops
        the wait (Ctrl-C, the time limit) closes the run, which would otherwise wait for its
        caller forever."""
        h = self._handoff
        try:
            got = 0
            deadline = time.monotonic() + START_TIMEOUT_S
            while time.monotonic() < deadline:
                got = h.wait(0.05)
                if got or self.done:
                    break
            if not self.done and got == 0:
                raise RunError(f"the run did not start stepping within {START_TIMEOUT_S:.0f} s")
        except BaseException:
            self._state.closing = True
            h.close("the caller stopped waiting for the run's start")
            raise
        finally:
            # The run has its controller, has ended or is closed: the entry is not needed.
            LOCAL.pop(self._token or "", None)
        if got == 1:
            first = h.first()
            obs = SimpleNamespace(**first)
            obs.ids = tuple(obs.ids)
            obs.controlled = np.array(obs.controlled, dtype=bool)
            obs.length_m = np.array(obs.length_m, dtype=np.float64)
            for key in ("controlled", "length_m"):
                getattr(obs, key).flags.writeable = False
            self._obs = obs
            self._unpack(h.take())
            return
        self._finish()
        raise self.error if self.error is not None else RunError("the run ended before its first step")

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
        self._unpack(packed)

    def _unpack(self, packed: bytes) -> None:
        assert self._obs is not None
        obs = self._obs
        values = np.frombuffer(packed, dtype=np.float64)
        obs.time_s, obs.step = float(values[0]), int(values[1])
        rows = values[2:].reshape(len(ROWS), -1)
        for key, row in zip(ROWS, rows):
            setattr(obs, key, row)

    def _receive_here(self, got: Optional[int] = None) -> None:
        """The next observation in this process (``got``: what the handoff said already), or
        the end of the run."""
        if (got or self._handoff.wait()) == 1:
            self._unpack(self._handoff.take())
        else:
            self._finish()
        self._pending = False

    def _finish(self) -> None:
        self._thread.join()
        self._state.done = True
        if self._conn is not None:
            self._conn.close()
        if self._listener is not None:
            self._listener.close()
        if self._state.error is not None:
            error, self._state.error = self._state.error, None
            raise error

    def _settle(self) -> None:
        """Receives the observation of a step whose commands went out but whose wait was
        interrupted (Ctrl-C): the run has stepped, so this is the current observation."""
        if self._pending and not self.done:
            if self._handoff is not None:
                self._receive_here()
            else:
                self._receive()
        self._pending = False

    def _refuse_after_interrupt(self) -> None:
        """Commands computed before an interrupted step would drive the step after it."""
        if self._pending:
            self._settle()
            raise RunError(
                "the previous step was interrupted after its commands went out, and the run "
                "has stepped since: observe() gives its observation, then step() again"
            )

    def observe(self) -> SimpleNamespace:
        """The observation at the current step (read-only arrays, indexed like ``obs.ids``)."""
        self._settle()
        if self._obs is None:
            raise RunError("the simulation has no observation")
        return self._obs

    @property
    def time_s(self) -> float:
        """Simulated time of the current observation [s]."""
        return float(self.observe().time_s)

    def command(self, speeds: "Union[Sequence[float], np.ndarray[Any, Any]]") -> None:
        """Sets the target speeds (one per vehicle of ``obs.ids``) the next ``step()`` without
        speeds sends; a later ``command`` replaces them."""
        self._commanded = self._checked(speeds)

    def step(self, speeds: "Union[Sequence[float], np.ndarray[Any, Any], None]" = None) -> Optional[SimpleNamespace]:
        """Commands ``speeds`` (one target speed per vehicle of ``obs.ids``; ``None``: those of
        the last ``command()``, else the current speeds) and advances one step; returns the new
        observation, or ``None`` when the run reached its horizon (``done``; the record is then
        in ``run``)."""
        if self.done:
            raise RunError("the simulation has ended; its record is in sim.run")
        self._refuse_after_interrupt()
        if speeds is not None:
            v = self._checked(speeds)
        elif self._commanded is not None:
            v = self._commanded
        else:
            v = self.observe().speed_mps.copy()
        self._commanded = None
        return self._advance(v)

    def _checked(self, speeds: "Union[Sequence[float], np.ndarray[Any, Any]]") -> "np.ndarray[Any, Any]":
        """``speeds`` as float64, one per vehicle of the observation."""
        obs = self.observe()
        v = np.array(speeds, dtype=np.float64)
        if v.shape != (len(obs.ids),):
            raise ScenarioError(
                f"speeds: {v.size} value(s) of shape {v.shape}; {len(obs.ids)} are needed, one per vehicle of obs.ids"
            )
        return v

    def _advance(self, v: "np.ndarray[Any, Any]") -> Optional[SimpleNamespace]:
        """``step`` with ``v`` checked: float64, one value per vehicle."""
        if self.done:
            raise RunError("the simulation has ended; its record is in sim.run")
        self._refuse_after_interrupt()
        # Until the next observation is in: an interrupted wait leaves the run a step ahead.
        self._pending = True
        if self._handoff is not None:
            self._receive_here(self._handoff.step(v.tobytes()))
        else:
            self._conn.send_bytes(v.tobytes())
            self._receive()
            self._pending = False
        return None if self.done else self._obs

    def close(self) -> Optional[Run]:
        """Ends the run (before its horizon: marked incomplete) and returns its :class:`Run`."""
        if not self.done:
            self._state.closing = True
            if self._handoff is not None:
                self._handoff.close(CLOSED)
                while not self.done:
                    self._receive_here()
                return self.run
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


class _RunState:
    """What a Simulation's run thread reports: its record, its error, its end."""

    def __init__(self) -> None:
        self.run: Optional[Run] = None
        self.error: Optional[BaseException] = None
        self.done = False
        #: The caller is closing the run (its "closed" stop is no error).
        self.closing = False


def _discarded(state: _RunState, handoff: Any, conn: Any) -> None:
    """Closes the run of a Simulation collected without close() (its thread ends the run and
    writes the record as close() would have)."""
    if state.done:
        return
    state.closing = True
    if handoff is not None:
        handoff.close(CLOSED)
    elif conn is not None:
        try:
            conn.send_bytes(b"")
        except OSError:
            pass


__all__ = ["Simulation"]
