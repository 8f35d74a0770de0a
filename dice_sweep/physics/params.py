"""Parameter vectors for the numba kernels.

The kernels take two flat arrays instead of a config object (numba nopython has no use for
dataclasses): ``fpar`` (float64) and ``ipar`` (int64), indexed by the constants below.
Module-level ints are compile-time constants in numba, so indexing costs nothing.

The state inside the kernels is that of the centre of mass (COM). With a loaded die
(``[effects] com_offset``) the COM sits at ``d`` (body frame) from the geometric centre, and
corner k seen from the COM is ``R e(2 pi k/n) - d``, stored as a radius rho_k and the cosine and
sine of its body angle gamma_k from index FP_CORNERS on.
"""

import math

import numpy as np

from dice_sweep.config import DEFAULT_CONTACT_WINDOW, MAX_EVENTS
from dice_sweep.geometry import inertia_ratio
from dice_sweep.physics.layout import METHODS, MODELS

# fpar indices (SI units)
FP_R = 0  # circumradius, m
FP_G = 1  # gravitational acceleration, m/s^2
FP_BN = 2  # beta_normal, 1
FP_BT = 3  # beta_tangential, 1
FP_WALL = 4  # half the wall separation, m (inf: no walls)
FP_DT = 5  # fixed_step time step, s
FP_TMAX = 6  # simulated time limit, s
FP_ALPHA = 7  # I_com / (M R^2), 1
FP_MU = 8  # Coulomb friction coefficient (inf: no cap)
FP_DRAG = 9  # quadratic air drag c, 1/m
FP_KSR = 10  # speed-dependent restitution k, s/m
FP_COM_X = 11  # centre-of-mass offset from the geometric centre, body frame, m
FP_COM_Y = 12
FP_INERTIA = 13  # I_com / M, m^2
FP_RHO_MAX = 14  # largest distance from the COM to a corner, m
FP_WINDOW = 15  # contact window: contacts arriving within it are one impact, s
FP_CONTACT_TIME = 16  # flat_landing effect: contact duration over which a second corner shares the impact, s
FP_DRAG_TOL = 17  # x rho_max: position error allowed per Runge-Kutta step of a flight with drag
FP_DRAG_MAX_STEP = 18  # s: longest Runge-Kutta step of a flight with drag
FP_CORNERS = 19  # then (rho_k, cos gamma_k, sin gamma_k) for k = 0..n-1
CORNER_STRIDE = 3

# ipar indices
IP_N = 0  # number of sides
IP_MODEL = 1  # contact model: MODEL_PAPER or MODEL_RIGID
IP_METHOD = 2  # integrator: METHOD_EVENT or METHOD_FIXED_STEP
IP_MAX_EVENTS = 3  # event budget per roll
IP_CONTINUE = 4  # 1: keep simulating after the decision, until rest or t_max (for fitting)
N_IPAR = 5

# Flight with drag (physics/flight.py): the defaults keep a sweep's flights exact to round-off;
# a fit, whose data are noisy by ~1e-4 m, may pass coarser ones (fpar, not config: no user sets them)
DRAG_TOL = 1e-13  # x rho_max
DRAG_MAX_STEP = 1e-3  # s



def _effects_values(cfg):
    """(air_drag, com_offset, speed_restitution, contact_time) of a config, off when absent."""
    effects = getattr(cfg, "effects", None)
    if effects is None:
        return 0.0, (0.0, 0.0), 0.0, 0.0
    return effects.air_drag, tuple(effects.com_offset), effects.speed_restitution, getattr(effects, "contact_time", 0.0)


def pack_params(cfg):
    """Flatten a validated :class:`dice_sweep.config.Config` into ``(fpar, ipar)``."""
    n = cfg.die.sides
    radius = cfg.die.circumradius
    drag, (dx, dy), k_speed, contact_time = _effects_values(cfg)
    fpar = np.zeros(FP_CORNERS + CORNER_STRIDE * n)
    fpar[FP_R] = radius
    fpar[FP_G] = cfg.world.g
    fpar[FP_BN] = cfg.contact.beta_normal
    fpar[FP_BT] = cfg.contact.beta_tangential
    sep = cfg.walls.separation
    fpar[FP_WALL] = math.inf if sep is None else 0.5 * sep
    fpar[FP_DT] = cfg.integrator.dt
    fpar[FP_TMAX] = cfg.integrator.t_max
    # parallel-axis rule: I about the COM is I about the centre less M d^2
    inertia = inertia_ratio(n) * radius * radius - (dx * dx + dy * dy)
    fpar[FP_INERTIA] = inertia
    fpar[FP_ALPHA] = inertia / (radius * radius)
    fpar[FP_MU] = getattr(cfg.contact, "friction", math.inf)
    fpar[FP_WINDOW] = getattr(cfg.contact, "window", DEFAULT_CONTACT_WINDOW)
    fpar[FP_CONTACT_TIME] = contact_time
    fpar[FP_DRAG] = drag
    fpar[FP_DRAG_TOL] = DRAG_TOL
    fpar[FP_DRAG_MAX_STEP] = DRAG_MAX_STEP
    fpar[FP_KSR] = k_speed
    fpar[FP_COM_X] = dx
    fpar[FP_COM_Y] = dy
    angles = 2.0 * math.pi * np.arange(n) / n
    bx = radius * np.cos(angles) - dx
    by = radius * np.sin(angles) - dy
    rho = np.hypot(bx, by)
    corners = fpar[FP_CORNERS:].reshape(n, CORNER_STRIDE)
    corners[:, 0] = rho
    corners[:, 1] = bx / rho
    corners[:, 2] = by / rho
    fpar[FP_RHO_MAX] = rho.max()
    ipar = np.zeros(N_IPAR, dtype=np.int64)
    ipar[IP_N] = n
    ipar[IP_MODEL] = MODELS[cfg.contact.model]
    ipar[IP_METHOD] = METHODS[cfg.integrator.method]
    ipar[IP_MAX_EVENTS] = event_budget(cfg.integrator)
    return fpar, ipar


def event_budget(integrator):
    """Events a roll may use: ``max_events``, and for ``fixed_step`` at least one per step
    (t_max / dt), since that scheme applies at most one impact per step and a die settling at a
    small step bounces on nearly every step (fig11 at dt = 1e-6 ran out in 8 of 1024 pixels)."""
    if integrator.method == "fixed_step":  # at most MAX_EVENTS: t_max / dt may be beyond int64
        return max(integrator.max_events, min(math.ceil(integrator.t_max / integrator.dt), MAX_EVENTS))
    return integrator.max_events
