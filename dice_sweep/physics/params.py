"""Parameter vectors for the numba kernels.

The kernels take two flat arrays instead of a config object (numba nopython has no use for
dataclasses): ``fpar`` (float64) and ``ipar`` (int64), indexed by the constants below.
Module-level ints are compile-time constants in numba, so indexing costs nothing.
"""

import math

import numpy as np

# fpar indices (SI units)
FP_R = 0  # circumradius, m
FP_G = 1  # gravitational acceleration, m/s^2
FP_BN = 2  # beta_normal, 1
FP_BT = 3  # beta_tangential, 1
FP_WALL = 4  # half the wall separation, m (inf: no walls)
FP_DT = 5  # fixed_step time step, s
FP_TMAX = 6  # simulated time limit, s
FP_ALPHA = 7  # I / (M R^2), 1
N_FPAR = 8

# ipar indices
IP_N = 0  # number of sides
IP_MODEL = 1  # contact model: MODEL_PAPER
IP_METHOD = 2  # integrator: METHOD_EVENT or METHOD_FIXED_STEP
IP_MAX_EVENTS = 3  # event budget per roll
N_IPAR = 4

MODEL_PAPER = 0
MODELS = {"paper": MODEL_PAPER}
METHOD_EVENT = 0
METHOD_FIXED_STEP = 1
METHODS = {"event": METHOD_EVENT, "fixed_step": METHOD_FIXED_STEP}


def inertia_ratio(sides):
    """alpha = I / (M R^2) of a uniform regular n-gon plate (Smith 2014, eq. 25)."""
    s = math.sin(math.pi / sides)
    c = math.cos(math.pi / sides)
    return s * s / 6.0 + c * c / 2.0


def pack_params(cfg):
    """Flatten a validated :class:`dice_sweep.config.Config` into ``(fpar, ipar)``."""
    fpar = np.zeros(N_FPAR)
    fpar[FP_R] = cfg.die.circumradius
    fpar[FP_G] = cfg.world.g
    fpar[FP_BN] = cfg.contact.beta_normal
    fpar[FP_BT] = cfg.contact.beta_tangential
    sep = cfg.walls.separation
    fpar[FP_WALL] = math.inf if sep is None else 0.5 * sep
    fpar[FP_DT] = cfg.integrator.dt
    fpar[FP_TMAX] = cfg.integrator.t_max
    fpar[FP_ALPHA] = inertia_ratio(cfg.die.sides)
    ipar = np.zeros(N_IPAR, dtype=np.int64)
    ipar[IP_N] = cfg.die.sides
    ipar[IP_MODEL] = MODELS[cfg.contact.model]
    ipar[IP_METHOD] = METHODS[cfg.integrator.method]
    ipar[IP_MAX_EVENTS] = cfg.integrator.max_events
    return fpar, ipar
