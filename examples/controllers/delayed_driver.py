"""The delayed-driver law of Proskurnikov & Mazo (eq. chandler+) on a bidirectional ring, as a
syncroad Python controller.

Driver i reacts after its own delay alpha_i to u_i = a_pred (v_{i-1} - v_i) + a_follow
(v_{i+1} - v_i). The speed over a step integrates the delayed input with the same fourth-order
stencil as syncroad's built-in law (weights -1, 13, 13, -1 over 24, delays of two or more
steps), from constant speeds before t = 0, so it reproduces the built-in law's trajectories
to rounding.

    "controller": {"python": "delayed_driver.py:DelayedDriver",
                   "params": {"gain_pred": 0.6, "gain_follow": 0.1, "delay_s": [0.5, 0.6, 0.7]}}

A list of delays shorter than the fleet repeats.
"""

import numpy as np


class DelayedDriver:
    def __init__(self, gain_pred, gain_follow, delay_s):
        self.gain_pred = float(gain_pred)
        self.gain_follow = float(gain_follow)
        self.delay_s = np.atleast_1d(np.asarray(delay_s, dtype=float))
        self.history = None

    def inputs(self, v):
        """u_i = a_pred (v_{i-1} - v_i) + a_follow (v_{i+1} - v_i) around the ring."""
        return self.gain_pred * (np.roll(v, 1) - v) + self.gain_follow * (np.roll(v, -1) - v)

    def step(self, obs):
        v = obs.speed_mps
        n = len(v)
        if self.history is None:
            delays = np.resize(self.delay_s, n)
            self.m = np.rint(delays / obs.dt_s).astype(int)
            if np.any(self.m < 2):
                raise ValueError("this example integrates delays of at least two steps")
            # Constant speeds before t = 0: every past input is the input at t = 0.
            self.history = [self.inputs(v)] * (int(self.m.max()) + 2)
        self.history.append(self.inputs(v))
        self.history = self.history[-(int(self.m.max()) + 2):]
        rows = np.arange(n)
        # History index -1 is u^n; u^{n-k} is index -1-k.
        h = np.array(self.history)
        a = h[-1 - (self.m + 1), rows]
        b = h[-1 - self.m, rows]
        c = h[-1 - (self.m - 1), rows]
        d = h[-1 - (self.m - 2), rows]
        return v + obs.dt_s * (13.0 * (b + c) - (a + d)) * (1.0 / 24.0)
