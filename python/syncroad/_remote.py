"""The controller a :class:`syncroad.Simulation` puts into its run: it lives where the run
steps its vehicles. In a SUMO worker process it hands each observation to the Simulation over
a local connection, waiting for the commands the caller gives; in the Simulation's own process
(SUMO on a thread of it, or the native simulator) syncroad's loop meets the caller in memory
through the ``Handoff`` the controller carries.

This file is loaded by path in the worker (as every user controller is), so it imports only
the standard library and numpy."""

import select
import time
from multiprocessing.connection import Client, Connection
from typing import Any, Callable, Dict, Optional

import numpy as np

#: The arrays of an observation sent every step, packed after (time_s, step) as float64.
ROWS = (
    "speed_mps",
    "accel_mps2",
    "odometer_m",
    "gap_m",
    "leader_speed_mps",
    "signal_distance_m",
    "signal_stop",
)
#: The fields sent once, with the first observation.
FIRST_FIELDS = ("dt_s", "ids", "controlled", "length_m", "ring_length_m", "speed_limit_mps")

#: The message that ends the run early (the caller closed the Simulation).
CLOSED = "the caller closed the simulation before its horizon"


#: How long a side looks for the other's next message before it blocks on the connection [s].
#: A blocked process is woken by the kernel, which costs more than a SUMO step of a small ring
#: (tens of microseconds, most of a step's round trip); looking for a few hundred microseconds
#: first answers at once when the other side is that quick.
SPIN_S = 0.0005

#: A look that found nothing (the other side is slower: a long computation, or more
#: processes than cores) makes the next 2, then 4, … up to this many receives block without
#: looking, as without spinning; a look that finds the message starts over.
SPIN_BACKOFF_MAX = 1024


class Receiver:
    """Receives the other side's messages on ``conn``: looks for the next one for up to
    :data:`SPIN_S` before blocking, less often while looking does not pay
    (:data:`SPIN_BACKOFF_MAX`). Timing only: the messages, and so the run, are the same either
    way."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.misses = 0
        self.skip = 0
        # One poll object on the connection's descriptor, registered once: a look is then one
        # system call (Connection.poll builds a selector each time, several times the cost).
        self.ready: Callable[[], bool] = lambda: conn.poll(0)
        if hasattr(select, "poll"):
            p = select.poll()
            p.register(conn.fileno(), select.POLLIN)
            self.ready = lambda: bool(p.poll(0))

    def recv_bytes(self) -> bytes:
        if self.skip > 0:
            self.skip -= 1
        else:
            ready = self.ready
            end = time.perf_counter() + SPIN_S
            while not ready():
                if time.perf_counter() >= end:
                    self.misses += 1
                    self.skip = min(2**self.misses, SPIN_BACKOFF_MAX)
                    break
            else:
                self.misses = 0
        return self.conn.recv_bytes()


class SimulationClosed(RuntimeError):
    """Ends the run when the caller closes the Simulation (``syncroad_stop``: the run's
    message is this text alone, without a traceback)."""

    syncroad_stop = True


#: The meeting points of this process's Simulations stepped here, by token: a
#: :class:`SimulationController` finds its own when the run unpickles it in this process.
LOCAL: Dict[str, Any] = {}


class SimulationController:
    """The controller a Simulation puts into its run. Stepped in a worker process
    (``address``, ``authkey``), it sends each observation to the Simulation over a local
    connection and returns its commands. Stepped in the Simulation's own process
    (``token``), it only carries the meeting point ``syncroad_handoff`` (a
    ``syncroad._syncroad.Handoff``) through which syncroad's loop hands each observation over
    and takes the commands without calling ``step``. Either way the run's record names it."""

    def __init__(self, address: Optional[str] = None, authkey: Optional[bytes] = None,
                 token: Optional[str] = None) -> None:
        self.address = address
        self.authkey = authkey
        self.token = token
        self.conn: Optional[Connection] = None
        self.receiver: Optional[Receiver] = None
        self.syncroad_handoff: Any = None

    def __getstate__(self) -> Dict[str, Any]:
        return {"address": self.address, "authkey": self.authkey, "token": self.token}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.address = state["address"]
        self.authkey = state["authkey"]
        self.token = state["token"]
        self.conn = None
        self.receiver = None
        self.syncroad_handoff = None
        if self.token is not None:
            # This file may be loaded by path under another name: the registry is the
            # package's.
            from syncroad import _remote

            self.syncroad_handoff = _remote.LOCAL.get(self.token)
            if self.syncroad_handoff is None:
                raise RuntimeError(
                    "this controller stands for a syncroad.Simulation of another process; it "
                    "runs only in the process that made it"
                )

    def step(self, obs: Any) -> "np.ndarray[Any, Any]":
        if self.address is None or self.authkey is None:
            raise RuntimeError("a Simulation's run in its own process hands its observations over without step()")
        conn = self.conn
        if conn is None:
            conn = self.conn = Client(self.address, authkey=self.authkey)
            self.receiver = Receiver(conn)
            conn.send({f: getattr(obs, f) for f in FIRST_FIELDS})
        # One message of raw float64 per step each way: no pickling in the loop.
        head = np.array([obs.time_s, obs.step], dtype=np.float64)
        conn.send_bytes(b"".join([head.tobytes()] + [getattr(obs, r).tobytes() for r in ROWS]))
        assert self.receiver is not None
        reply = self.receiver.recv_bytes()
        if not reply:
            raise SimulationClosed(CLOSED)
        return np.frombuffer(reply, dtype=np.float64)
