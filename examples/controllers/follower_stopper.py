"""The FollowerStopper of Stern et al. (2018) as a syncroad Python controller.

A vectorised numpy version of syncroad's built-in `follower-stopper-U`: the same band edges
and command, tracked within the vehicle's acceleration limits. With the defaults of the
scenario's vehicle type (accel 2.6, decel 4.5 m/s^2) it reproduces the built-in law's
trajectories to rounding.

    "controller": {"python": "follower_stopper.py:FollowerStopper",
                   "params": {"desired_speed_mps": 4.3}}

Reference: R. E. Stern et al., "Dissipation of stop-and-go waves via control of autonomous
vehicles: Field experiments", Transp. Res. C 89 (2018) 205-221.
"""

import numpy as np


class FollowerStopper:
    def __init__(self, desired_speed_mps, accel_mps2=2.6, decel_mps2=4.5,
                 dx0_m=(4.5, 5.25, 6.0), band_decel_mps2=(1.5, 1.0, 0.5)):
        self.u = float(desired_speed_mps)
        self.accel = float(accel_mps2)
        self.decel = float(decel_mps2)
        self.dx0 = [float(x) for x in dx0_m]
        self.d = [float(x) for x in band_decel_mps2]

    def command_mps(self, v, gap, v_lead):
        """The command velocity of each vehicle (Stern et al., eq. for v_cmd)."""
        closing = np.minimum(v_lead - v, 0.0)
        x1, x2, x3 = (self.dx0[k] + closing * closing / (2.0 * self.d[k]) for k in range(3))
        target = np.minimum(np.maximum(v_lead, 0.0), self.u)
        return np.where(
            gap <= x1, 0.0,
            np.where(gap <= x2, target * (gap - x1) / (x2 - x1),
                     np.where(gap <= x3, target + (self.u - target) * (gap - x2) / (x3 - x2),
                              self.u)))

    def step(self, obs):
        v = obs.speed_mps
        with np.errstate(invalid="ignore", divide="ignore"):
            cmd = self.command_mps(v, obs.gap_m, obs.leader_speed_mps)
        # Nobody ahead (an open road's first vehicle): drive at the desired speed.
        cmd = np.where(np.isnan(obs.leader_speed_mps), self.u, cmd)
        dv = np.clip(cmd - v, -self.decel * obs.dt_s, self.accel * obs.dt_s)
        return np.maximum(v + dv, 0.0)
