"""The controller a :class:`syncroad.Simulation` puts into its run: it lives where the run
steps its vehicles (the SUMO worker, or this process natively) and hands each observation to
the Simulation over a local connection, waiting for the commands the caller gives.

This file is loaded by path in the worker (as every user controller is), so it imports only
the standard library and numpy."""

from multiprocessing.connection import Client, Connection
from typing import Any, Dict, Optional

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


class SimulationClosed(RuntimeError):
    """Ends the run when the caller closes the Simulation (``syncroad_stop``: the run's
    message is this text alone, without a traceback)."""

    syncroad_stop = True


class RemoteController:
    """Sends each observation to the Simulation at ``address`` and returns its commands."""

    def __init__(self, address: str, authkey: bytes) -> None:
        self.address = address
        self.authkey = authkey
        self.conn: Optional[Connection] = None

    def __getstate__(self) -> Dict[str, Any]:
        return {"address": self.address, "authkey": self.authkey}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.address = state["address"]
        self.authkey = state["authkey"]
        self.conn = None

    def step(self, obs: Any) -> "np.ndarray[Any, Any]":
        conn = self.conn
        if conn is None:
            conn = self.conn = Client(self.address, authkey=self.authkey)
            conn.send({f: getattr(obs, f) for f in FIRST_FIELDS})
        # One message of raw float64 per step each way: no pickling in the loop.
        head = np.array([obs.time_s, obs.step], dtype=np.float64)
        conn.send_bytes(b"".join([head.tobytes()] + [getattr(obs, r).tobytes() for r in ROWS]))
        reply = conn.recv_bytes()
        if not reply:
            raise SimulationClosed(CLOSED)
        return np.frombuffer(reply, dtype=np.float64)
