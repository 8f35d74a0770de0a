"""Parameter vectors for the numba kernels.

The kernels take two flat arrays instead of a config object (numba nopython has no use for
dataclasses): ``fpar`` (float64) and ``ipar`` (int64), indexed by the constants below.
Module-level ints are compile-time constants in numba, so indexing costs nothing.

The state inside the kernels is that of the centre of mass (COM). With a loaded die
(``[effects] com_offset``) the COM sits at ``d`` (body frame) from the geometric centre, and
corner k seen from the COM is ``R e(2 pi k/n) - d``, stored as a radius rho_k and the cosine and
sine of its body angle gamma_k from index FP_CORNERS on.

Rounded corners (``[effects] corner_radius`` r > 0, fpar[FP_CORNER_RADIUS]): the die is a core
regular polygon of apothem a - r (a = R cos(pi/n), the sharp die's) grown by a disk of radius r,
and the corner block holds the core's corners, the arc centres: ``Rc e(2 pi k/n) - d`` with
Rc = (a - r) / cos(pi/n). A surface is touched where an arc centre is r from it. FP_RHO_MAX is
then the die's reach from the COM, max rho_k + r (docs/physics.md, "Rounded corners").
"""

import math

import numpy as np

from dice_sweep import effects as effect_registry
from dice_sweep.config import MAX_EVENTS
from dice_sweep.geometry import core_circumradius, inertia_ratio
from dice_sweep.physics.layout import METHODS, MODELS

# fpar indices (SI units): the base slots; every effect's slots follow, from the registry
FP_R = 0  # circumradius, m
FP_G = 1  # gravitational acceleration, m/s^2
FP_BN = 2  # beta_normal, 1
FP_BT = 3  # beta_tangential, 1
FP_WALL = 4  # half the wall separation, m (inf: no walls)
FP_DT = 5  # fixed_step time step, s
FP_TMAX = 6  # simulated time limit, s
FP_ALPHA = 7  # I_com / (M R^2), 1
FP_MU = 8  # Coulomb friction coefficient (inf: no cap)
FP_INERTIA = 9  # I_com / M, m^2 (the inertia effect's factor times eq. 25, less M d^2 of a loaded die)
FP_RHO_MAX = 10  # largest distance from the COM to a point of the die (a corner, or an arc's far side), m
FP_WINDOW = 11  # contact window: contacts arriving within it are one impact, s
FP_DRAG_TOL = 12  # x rho_max: position error allowed per Runge-Kutta step of a flight with drag
FP_DRAG_MAX_STEP = 13  # s: longest Runge-Kutta step of a flight with drag
# a roll's random stream (seed, pixel, draw) for the stochastic impact law (physics/scatter.py),
# integers below 2^53 stored as floats: pixel and draw set per roll by the batch; the seed and
# the law's spreads (FP_SCATTER_*, floors in m/s) are the registry's [scatter] slots
FP_STREAM_PIXEL = 14
FP_STREAM_DRAW = 15
N_FP_BASE = 16

# ipar indices
IP_N = 0  # number of sides
IP_MODEL = 1  # contact model: MODEL_PAPER or MODEL_RIGID
IP_METHOD = 2  # integrator: METHOD_EVENT or METHOD_FIXED_STEP
IP_MAX_EVENTS = 3  # event budget per roll
IP_CONTINUE = 4  # 1: keep simulating after the decision, until rest or t_max (for fitting)
N_IP_BASE = 5


def _registry_slots():
    """{slot name: (vector, index, config key)} of every kernel slot the effect registry
    declares: ``FP_*`` names in fpar after the base slots (an array key takes consecutive
    ones), ``IP_*`` names (choices, packed as their index) in ipar. Effects are added in the
    registry only (dice_sweep/effects.py); their slots follow from it."""
    slots = {}
    next_index = {"fpar": N_FP_BASE, "ipar": N_IP_BASE}
    for section in effect_registry.config_key_specs().values():
        for key in section.values():
            if not key.slot:
                continue
            vector = "ipar" if key.slot.startswith("IP_") else "fpar"
            slots[key.slot] = (vector, next_index[vector], key)
            next_index[vector] += max(key.length, 1)
    return slots, next_index["fpar"], next_index["ipar"]


SLOTS, FP_CORNERS, N_IPAR = _registry_slots()
# Each slot is a module-level int here (FP_DRAG, IP_FRICTION_RULE, ...), so a kernel module
# imports it by name and numba compiles it as a constant.
globals().update({name: index for name, (_, index, _) in SLOTS.items()})
FP_COM_Y = FP_COM_X + 1  # noqa: F821  (FP_COM_X: the com_offset key's slot, from the registry)
CORNER_STRIDE = 3  # after FP_CORNERS: (rho_k, cos gamma_k, sin gamma_k) for k = 0..n-1

# Flight with drag (physics/flight.py): the defaults keep a sweep's flights exact to round-off;
# a fit, whose data are noisy by ~1e-4 m, may pass coarser ones (fpar, not config: no user sets them)
DRAG_TOL = 1e-13  # x rho_max
DRAG_MAX_STEP = 1e-3  # s


# The base keys a fit frees, each copied into its slot as it is (the registry's keys follow SLOTS)
BASE_KEY_SLOTS = {"world.g": FP_G, "contact.beta_normal": FP_BN, "contact.beta_tangential": FP_BT, "contact.friction": FP_MU}
# The inertia effect's factor has no slot: it enters FP_INERTIA and FP_ALPHA (_pack_derived)
INERTIA_KEY = "effects.inertia"


def _slot_of(dotted_key):
    """(vector, index, registry ConfigKey or None) of a config key: a base key of
    BASE_KEY_SLOTS or a registry key, with ``[i]`` for a component of an array key
    (``"effects.com_offset[1]"``)."""
    name, _, item = dotted_key.partition("[")
    offset = int(item.rstrip("]")) if item else 0
    if name in BASE_KEY_SLOTS and not item:
        return "fpar", BASE_KEY_SLOTS[name], None
    for vector, index, key in SLOTS.values():
        if key.dotted == name and offset < max(key.length, 1):
            return vector, index + offset, key
    raise KeyError(f"{dotted_key} has no kernel slot in the effect registry")


def slot(dotted_key):
    """The kernel index of a config key (``"effects.air_drag"`` -> FP_DRAG's index,
    ``"effects.com_offset[1]"`` -> FP_COM_Y, ``"world.g"`` -> FP_G)."""
    return _slot_of(dotted_key)[1]


def _write_slot(key, value, fpar, ipar, index):
    """A registry key's value into its slot (a choice as its index, an array in consecutive slots)."""
    if key.choices:
        ipar[index] = key.choices.index(value)
    elif key.length:
        fpar[index:index + key.length] = value
    else:
        fpar[index] = value


def _pack_registry_slots(cfg, fpar, ipar):
    """Fill every registry slot from the config's value of its key."""
    for _, index, key in SLOTS.values():
        _write_slot(key, key.packed(cfg, effect_registry.get_key(cfg, key.dotted)), fpar, ipar, index)


def _pack_derived(fpar, sides, inertia):
    """The slots computed from others: the moment of inertia about the COM (the inertia
    ``factor`` times eq. 25, less M d^2 of a loaded die), its ratio, the corners seen from the
    COM and the die's reach, from the radius, centre-of-mass and corner-radius slots."""
    radius = fpar[FP_R]
    dx, dy = fpar[FP_COM_X], fpar[FP_COM_Y]  # noqa: F821
    # parallel-axis rule: I about the COM is I about the centre less M d^2
    moment = inertia * inertia_ratio(sides) * radius * radius - (dx * dx + dy * dy)
    fpar[FP_INERTIA] = moment
    fpar[FP_ALPHA] = moment / (radius * radius)
    angles = 2.0 * math.pi * np.arange(sides) / sides
    corner_radius = fpar[FP_CORNER_RADIUS]  # noqa: F821  (the rounded_corners key's slot)
    # rounded corners: the arc centres, corners of the core polygon of apothem a - r
    core = radius if corner_radius == 0.0 else core_circumradius(sides, radius, corner_radius)
    bx = core * np.cos(angles) - dx
    by = core * np.sin(angles) - dy
    rho = np.hypot(bx, by)
    corners = fpar[FP_CORNERS:].reshape(sides, CORNER_STRIDE)
    corners[:, 0] = rho
    corners[:, 1] = bx / rho
    corners[:, 2] = by / rho
    fpar[FP_RHO_MAX] = rho.max() + corner_radius


def pack_params(cfg):
    """Flatten a validated :class:`dice_sweep.config.Config` into ``(fpar, ipar)``."""
    n = cfg.die.sides
    radius = cfg.die.circumradius
    fpar = np.zeros(FP_CORNERS + CORNER_STRIDE * n)
    ipar = np.zeros(N_IPAR, dtype=np.int64)
    _pack_registry_slots(cfg, fpar, ipar)
    fpar[FP_R] = radius
    for key, index in BASE_KEY_SLOTS.items():
        fpar[index] = effect_registry.get_key(cfg, key)
    sep = cfg.walls.separation
    fpar[FP_WALL] = math.inf if sep is None else 0.5 * sep
    fpar[FP_DT] = cfg.integrator.dt
    fpar[FP_TMAX] = cfg.integrator.t_max
    fpar[FP_WINDOW] = cfg.contact.window
    fpar[FP_DRAG_TOL] = DRAG_TOL
    fpar[FP_DRAG_MAX_STEP] = DRAG_MAX_STEP
    _pack_derived(fpar, n, effect_registry.get_key(cfg, INERTIA_KEY))
    ipar[IP_N] = n
    ipar[IP_MODEL] = MODELS[cfg.contact.model]
    ipar[IP_METHOD] = METHODS[cfg.integrator.method]
    ipar[IP_MAX_EVENTS] = event_budget(cfg.integrator)
    return fpar, ipar


class KeyWriter:
    """A config's packed vectors, and copies of ``fpar`` with values of config keys written
    straight into their slots: a fit moves its parameters evaluation after evaluation without
    building and packing a config each time.

    Parameters
    ----------
    cfg : Config
        Everything the written values leave alone (switches, the die, the integrator).
    """

    def __init__(self, cfg):
        self.fpar, self.ipar = pack_params(cfg)
        self.sides = cfg.die.sides
        self.inertia = effect_registry.get_key(cfg, INERTIA_KEY)
        self.cfg = cfg  # the unit of a key in the die's own units (a scatter floor's sqrt(g R))

    def fpar_with(self, values):
        """A copy of ``fpar`` with ``values`` ({dotted config key: number}, a component of an
        array key as ``key[i]``) in their float slots and the derived slots recomputed: the
        ``fpar`` of the config with those values set, bit for bit."""
        fpar = self.fpar.copy()
        inertia = self.inertia
        for key, value in values.items():
            if key == INERTIA_KEY:
                inertia = float(value)
                continue
            vector, index, spec = _slot_of(key)
            if vector != "fpar":
                raise KeyError(f"{key} is a choice (ipar), not a number to write")
            fpar[index] = float(value) if spec is None else spec.packed(self.cfg, float(value))
        _pack_derived(fpar, self.sides, inertia)
        return fpar


def event_budget(integrator):
    """Events a roll may use: ``max_events``, and for ``fixed_step`` at least one per step
    (t_max / dt), since that scheme applies at most one impact per step and a die settling at a
    small step bounces on nearly every step (fig11 at dt = 1e-6 ran out in 8 of 1024 pixels)."""
    if integrator.method == "fixed_step":  # at most MAX_EVENTS: t_max / dt may be beyond int64
        return max(integrator.max_events, min(math.ceil(integrator.t_max / integrator.dt), MAX_EVENTS))
    return integrator.max_events
