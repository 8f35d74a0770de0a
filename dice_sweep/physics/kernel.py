"""PLACEHOLDER kernel with the final signature; the real physics replaces it (issue 2)."""

import math

import numba
import numpy as np

from dice_sweep.physics.params import FP_G, FP_R, IP_N

STATE_COLUMNS = ("x0", "y0", "phi0", "vx0", "vy0", "omega0")
STATUS_NAMES = ("decided", "t_max", "event_budget", "balanced", "stalled")
COUNT_COLUMNS = ("impacts", "wall_impacts", "corner_fallbacks", "pivots", "energy_clips")


@numba.njit(cache=True)
def roll_batch(fpar, ipar, states, out_outcome, out_status, out_counts, out_t):
    n = ipar[IP_N]
    for i in range(states.shape[0]):
        t_fall = math.sqrt(2.0 * max(states[i, 1] - fpar[FP_R], 0.0) / fpar[FP_G])
        turns = (states[i, 2] + states[i, 5] * t_fall) / (2.0 * math.pi / n)
        out_outcome[i] = int(math.floor(turns)) % n
        out_status[i] = 0
        for j in range(out_counts.shape[1]):
            out_counts[i, j] = 0
        out_counts[i, 0] = 1
        out_t[i] = t_fall
