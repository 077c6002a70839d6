"""The controller a :class:`syncroad.Simulation` puts into its run: it lives where the run
steps its vehicles (the SUMO worker, or this process natively) and hands each observation to
the Simulation over a local connection, waiting for the commands the caller gives.

This file is loaded by path in the worker (as every user controller is), so it imports only
the standard library and numpy."""

from multiprocessing.connection import Client, Connection
from typing import Any, Dict, Optional

import numpy as np

#: Fields of an observation sent every step (the constant ones go with the first).
STEP_FIELDS = ("time_s", "step", "speed_mps", "accel_mps2", "odometer_m", "gap_m", "leader_speed_mps")
FIRST_FIELDS = ("dt_s", "ids", "controlled", "length_m", "ring_length_m")

#: The message that ends the run early (the caller closed the Simulation).
CLOSED = "the caller closed the simulation before its horizon"


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
        first = conn is None
        if conn is None:
            conn = self.conn = Client(self.address, authkey=self.authkey)
        msg = {f: getattr(obs, f) for f in STEP_FIELDS}
        if first:
            msg.update({f: getattr(obs, f) for f in FIRST_FIELDS})
        conn.send(msg)
        kind, speeds = conn.recv()
        if kind == "close":
            raise RuntimeError(CLOSED)
        return np.asarray(speeds, dtype=np.float64)
