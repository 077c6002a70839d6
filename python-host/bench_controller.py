"""The Python controller of syncroad's SUMO benchmark (`syncroad sumo-bench`): the speed law
of the TraCI reference loop, `v_i + Δt g (v_{i−1} − v_i)`, vectorised with numpy. The
benchmark runs it inside syncroad's worker (one call per step) and from the TraCI reference
loop (as Flow calls its controllers), so the two differ only in how the law is driven."""

import numpy as np


class Follow:
    def __init__(self, gain=0.5):
        self.gain = gain

    def step(self, obs):
        v = obs.speed_mps
        # The speed ahead, v_{i-1} (vehicle 0 follows the last): the same as np.roll(v, 1),
        # which alone costs about 6 µs at N = 22, four times these two slices.
        ahead = np.concatenate((v[-1:], v[:-1]))
        return v + obs.dt_s * self.gain * (ahead - v)
