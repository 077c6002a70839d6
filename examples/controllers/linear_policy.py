"""A policy trained in syncroad's learning environment, as a syncroad Python controller.

The policy of ``examples/learning/train_ring.py``: from each automated vehicle's ``local``
observation (its speed, its gap and the speed ahead, divided by 30 m/s, the ring's length and
30 m/s, clipped to [0, 1]) the action ``x = tanh(w · o + b)`` in [-1, 1], the fraction of the
vehicle type's deceleration (x < 0) or acceleration (x > 0), and the speed ``max(v + a Δt, 0)``:
exactly what ``syncroad.gym.RingEnv`` does with the same action, so the policy drives a
scenario as it drove the environment (a test checks every speed of an episode).

    "controller": {"python": "linear_policy.py:LinearPolicy",
                   "params": {"policy": "../examples/learning/ring-policy.json"}}

``policy`` is the JSON file the training writes (relative paths from the current folder), or
its content as a dict:
``{"weights": [w_v, w_gap, w_ahead], "bias": b, "speed_scale_mps": 30, "accel_mps2": 2.6,
"decel_mps2": 4.5}``.
"""

import json
import math

import numpy as np


class LinearPolicy:
    def __init__(self, policy):
        if isinstance(policy, dict):
            p = policy
        else:
            with open(policy) as f:
                p = json.load(f)
        self.w = [float(x) for x in p["weights"]]
        if len(self.w) != 3:
            raise ValueError(f"policy {policy}: weights = {p['weights']!r}; 3 are needed "
                             "(speed, gap, speed ahead)")
        self.b = float(p["bias"])
        self.vs = float(p.get("speed_scale_mps", 30.0))
        self.accel = float(p.get("accel_mps2", 2.6))
        self.decel = float(p.get("decel_mps2", 4.5))

    @staticmethod
    def _clip01(x):
        # nan (nobody ahead) → 0; inf (no gap) → 1.
        return (1.0 if x > 1.0 else x) if x > 0.0 else 0.0

    def action(self, v, gap, ahead, gap_scale):
        """The action in [-1, 1] for one vehicle's speed, gap and speed ahead."""
        o = (self._clip01(v / self.vs), self._clip01(gap / gap_scale), self._clip01(ahead / self.vs))
        # The observation is float32 in the environment: the same rounding here.
        return self.act([float(np.float32(x)) for x in o])

    def act(self, o):
        """The action in [-1, 1] for the environment's observation ``o`` (3 values)."""
        o0, o1, o2 = (float(x) for x in o)
        return math.tanh(self.w[0] * o0 + self.w[1] * o1 + self.w[2] * o2 + self.b)

    def step(self, obs):
        v = obs.speed_mps
        out = v.copy()
        gs = float(obs.ring_length_m or 100.0)
        for i in np.flatnonzero(obs.controlled):
            x = self.action(v.item(i), obs.gap_m.item(i), obs.leader_speed_mps.item(i), gs)
            a = x * (self.accel if x >= 0.0 else self.decel)
            out[i] = max(v.item(i) + a * obs.dt_s, 0.0)
        return out
