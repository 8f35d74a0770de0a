"""The die simulated by pymunk (Chipmunk2D), an engine written by no one here (issue 4).

A reference for the kernel's ``rigid`` contact model with ``beta_tangential = 0``: Newton
restitution at the touching corners and Coulomb friction, solved by Chipmunk's iterative
impulse solver over fixed steps. The set-up and the choice of every solver setting are
explained in docs/validation.md.

pymunk is a test-only dependency: it is imported inside the functions that need it.

Chipmunk's step (cpSpaceStep) moves the positions with the velocities first, then finds the
contacts, adds gravity to the velocities and solves the contacts. So in flight the stored
velocity is the mean over the next step, v(t + dt/2), and the positions are exact. The die is
started with v(dt/2) and its reported velocity is shifted back by half a step of gravity.
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from dice_sweep.config import parse_config
from dice_sweep.geometry import corners, side_below

STATUS_DECIDED = 0
STATUS_T_MAX = 1
STATUS_NAMES = ("decided", "t_max")
# Same relative margin as the kernel's energy rule (dice_sweep.physics.kernel.DECISION_MARGIN).
DECISION_MARGIN = 1e-12
MASS = 1.0  # kg; outcomes do not depend on it
TABLE_HALF_LENGTH = 10.0  # m, without walls: far beyond any slide of a centimetre die
WALL_HEIGHT = 10.0  # m, far above any bounce


@dataclass(frozen=True)
class PymunkSettings:
    """Solver settings of the pymunk space (docs/validation.md says why these values).

    Attributes
    ----------
    iterations : int
        Passes of the iterative impulse solver per step (pymunk's default is 10).
    collision_slop : float
        Overlap, m, that pymunk leaves uncorrected (its default, 0.1, is 7 circumradii here).
    overlap_fixed_per_step : float
        Share of the remaining overlap that the position correction removes in each step;
        sets ``Space.collision_bias = (1 - share) ** (1 / dt)``.
    """

    iterations: int = 30
    collision_slop: float = 1e-5
    overlap_fixed_per_step: float = 0.01

    def collision_bias(self, dt):
        """pymunk's ``collision_bias``: the share of overlap left after one second of steps dt (s)."""
        return (1.0 - self.overlap_fixed_per_step) ** (1.0 / dt)


@dataclass(frozen=True)
class PymunkBatch:
    """Results of :func:`pymunk_batch`, one entry per initial state.

    Attributes
    ----------
    outcome : numpy.ndarray of int8
        Side 0..n-1, -1 when undecided.
    status : numpy.ndarray of uint8
        0 decided, 1 not decided by t_max (``STATUS_NAMES``).
    t_decided : numpy.ndarray of float64
        Simulated time, s, at which the side was decided; NaN when undecided.
    contacts : numpy.ndarray of int32
        Times the die started touching a surface it had left (pymunk ``begin`` callbacks).
    """

    outcome: np.ndarray
    status: np.ndarray
    t_decided: np.ndarray
    contacts: np.ndarray


class PymunkDie:
    """One n-gon die in its own pymunk space: table at y = 0, optional walls at x = +-separation/2.

    Parameters
    ----------
    sides, circumradius : int, float
        The die: n >= 3 corners on a circle of radius R, m.
    beta_normal : float
        Newton restitution of the touching corner's normal velocity, in [0, 1].
    friction : float
        Coulomb coefficient mu, finite (Chipmunk computes mu times the normal impulse, which is
        NaN for an infinite mu before the first push).
    g : float
        Gravitational acceleration, m/s^2.
    state : array_like, shape (6,)
        Initial (x, y, phi, vx, vy, omega) in SI units, columns of ``STATE_COLUMNS``.
    dt : float
        Fixed step, s.
    separation : float, optional
        Distance between the walls, m; None: no walls.
    settings : PymunkSettings, optional
        Solver settings.
    """

    def __init__(self, sides, circumradius, beta_normal, friction, g, state, *, dt=1e-4, separation=None,
                 settings=PymunkSettings()):
        import pymunk

        if not math.isfinite(friction):
            raise ValueError(f"pymunk needs a finite friction coefficient, got {friction}")
        self.sides = sides
        self.circumradius = circumradius
        self.g = g
        self.dt = dt
        self.steps = 0
        self.contacts = 0
        self.space = pymunk.Space()
        self.space.gravity = (0.0, -g)
        self.space.iterations = settings.iterations
        self.space.collision_slop = settings.collision_slop
        self.space.collision_bias = settings.collision_bias(dt)
        # Chipmunk multiplies the two shapes' elasticities and frictions: the surfaces carry 1.
        for surface in _surfaces(pymunk, self.space.static_body, separation):
            surface.elasticity = 1.0
            surface.friction = 1.0
            self.space.add(surface)
        vertices = [tuple(corner) for corner in corners(sides, circumradius, 0.0, 0.0, 0.0)]
        self.body = pymunk.Body(MASS, pymunk.moment_for_poly(MASS, vertices))
        die = pymunk.Poly(self.body, vertices, radius=0.0)
        die.elasticity = beta_normal
        die.friction = friction
        x, y, phi, vx, vy, omega = np.asarray(state, dtype=float)
        self.body.position = (x, y)
        self.body.angle = phi
        self.body.velocity = (vx, vy - 0.5 * g * dt)  # the mean velocity over the first step
        self.body.angular_velocity = omega
        self.space.add(self.body, die)
        self.moment_per_mass = self.body.moment / MASS  # I/M, m^2
        self.space.on_collision(begin=self._count_contact)

    @classmethod
    def from_config(cls, cfg, state, *, friction=None, dt=1e-4, settings=PymunkSettings()):
        """The die, surfaces and coefficients of a config (see :func:`pymunk_batch`), started at ``state``."""
        return cls(cfg.die.sides, cfg.die.circumradius, cfg.contact.beta_normal,
                   cfg.contact.friction if friction is None else friction, cfg.world.g, state, dt=dt,
                   separation=cfg.walls.separation, settings=settings)

    def _count_contact(self, arbiter, space, data):
        self.contacts += 1

    @property
    def time(self):
        """Simulated time, s."""
        return self.steps * self.dt

    def step(self):
        """Advance the space by one step dt."""
        self.space.step(self.dt)
        self.steps += 1

    def state(self):
        """(x, y, phi, vx, vy, omega) at :attr:`time`, SI units, velocity shifted back dt/2."""
        position, velocity = self.body.position, self.body.velocity
        return np.array([position.x, position.y, self.body.angle, velocity.x,
                         velocity.y + 0.5 * self.g * self.dt, self.body.angular_velocity])

    def specific_energy(self):
        """E/M = (vx^2 + vy^2)/2 + (I/M) omega^2/2 + g y at :attr:`time`, J/kg."""
        # called every step: plain floats, no array
        velocity, omega = self.body.velocity, self.body.angular_velocity
        vy = velocity.y + 0.5 * self.g * self.dt
        kinetic = 0.5 * (velocity.x * velocity.x + vy * vy) + 0.5 * self.moment_per_mass * omega * omega
        return kinetic + self.g * self.body.position.y

    def is_decided(self):
        """True once E/M < g R (1 - 1e-12): no corner can pass under the centre again."""
        return self.specific_energy() < self.g * self.circumradius * (1.0 - DECISION_MARGIN)

    def run(self, t_max):
        """Step until the side is decided by the kernel's energy rule, or until t_max (s).

        Returns
        -------
        outcome : int
            Side 0..n-1, -1 when undecided.
        status : int
            0 decided, 1 not decided by t_max.
        t_decided : float
            Simulated time of the decision, s (a multiple of dt); NaN when undecided.
        contacts : int
            Times the die started touching a surface it had left (pymunk ``begin`` callbacks);
            a corner landing while another corner still touches is not counted.
        """
        while self.time <= t_max:
            if self.is_decided():
                return self.side_below(), STATUS_DECIDED, self.time, self.contacts
            self.step()
        return -1, STATUS_T_MAX, math.nan, self.contacts

    def side_below(self):
        """Side crossed by the vertical ray down from the centre (side k: corners k and k+1)."""
        return side_below(self.sides, self.body.angle)


def _surfaces(pymunk, static_body, separation):
    """Static segments: the table, and two walls when ``separation`` (m) is given."""
    if separation is None:
        return [pymunk.Segment(static_body, (-TABLE_HALF_LENGTH, 0.0), (TABLE_HALF_LENGTH, 0.0), 0.0)]
    half = 0.5 * separation
    return [
        pymunk.Segment(static_body, (-half, 0.0), (half, 0.0), 0.0),
        pymunk.Segment(static_body, (-half, 0.0), (-half, WALL_HEIGHT), 0.0),
        pymunk.Segment(static_body, (half, 0.0), (half, WALL_HEIGHT), 0.0),
    ]


def pymunk_roll(sides, circumradius, beta_normal, friction, g, state, *, dt=1e-4, t_max=5.0, separation=None,
                settings=PymunkSettings()):
    """Drop one die in pymunk and stop when its side is decided by the kernel's energy rule.

    Parameters
    ----------
    sides, circumradius, beta_normal, friction, g, state, dt, separation, settings
        As in :class:`PymunkDie` (SI units).
    t_max : float
        Simulated time limit, s.

    Returns
    -------
    outcome, status, t_decided, contacts
        As :meth:`PymunkDie.run`.
    """
    die = PymunkDie(sides, circumradius, beta_normal, friction, g, state, dt=dt, separation=separation,
                    settings=settings)
    return die.run(t_max)


def pymunk_batch(cfg, states, *, friction=None, dt=1e-4, t_max=5.0, settings=PymunkSettings()):
    """Roll many dice of one config in pymunk, one after the other.

    Parameters
    ----------
    cfg : dice_sweep.config.Config or alike
        Uses ``die.sides``, ``die.circumradius``, ``contact.beta_normal``, ``world.g`` and
        ``walls.separation``; ``contact.friction`` unless ``friction`` is given.
    states : array_like, shape (N, 6)
        Initial states, columns ``STATE_COLUMNS`` (SI units).
    friction : float, optional
        Coulomb coefficient; by default ``cfg.contact.friction``.
    dt, t_max, settings
        As in :func:`pymunk_roll`.

    Returns
    -------
    PymunkBatch
    """
    rolls = [
        PymunkDie.from_config(cfg, state, friction=friction, dt=dt, settings=settings).run(t_max)
        for state in np.asarray(states, dtype=float)
    ]
    outcome, status, t_decided, contacts = zip(*rolls) if rolls else ((), (), (), ())
    return PymunkBatch(
        outcome=np.array(outcome, dtype=np.int8),
        status=np.array(status, dtype=np.uint8),
        t_decided=np.array(t_decided, dtype=np.float64),
        contacts=np.array(contacts, dtype=np.int32),
    )


def pymunk_outcomes(cfg, states, **options):
    """Sides (int8, -1 undecided) of :func:`pymunk_batch` for the same arguments."""
    return pymunk_batch(cfg, states, **options).outcome


# --- comparing outcome maps ------------------------------------------------------------------


def settled_mask(outcome_map, width=3):
    """Pixels away from basin boundaries: their width x width neighbourhood holds one side only.

    Parameters
    ----------
    outcome_map : array_like of int, shape (ny, nx)
        Sides, -1 undecided (an undecided pixel is never settled).
    width : int
        Odd side of the square neighbourhood; it is clipped at the edges of the map.

    Returns
    -------
    numpy.ndarray of bool, shape (ny, nx)
    """
    outcome_map = np.asarray(outcome_map)
    half = width // 2
    # edge padding repeats border pixels, which is the same as clipping the neighbourhood
    padded = np.pad(outcome_map, half, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, (width, width))
    return (windows == outcome_map[:, :, None, None]).all(axis=(2, 3)) & (outcome_map >= 0)


def map_agreement(first, second, mask=None):
    """Share of pixels on which two outcome maps give the same side.

    Parameters
    ----------
    first, second : array_like of int, shape (ny, nx)
        Sides, -1 undecided (two undecided pixels count as agreeing).
    mask : array_like of bool, shape (ny, nx), optional
        Pixels to compare; by default all.

    Returns
    -------
    share : float
        In [0, 1]; NaN when the mask is empty.
    count : int
        Pixels compared.
    """
    first, second = np.asarray(first), np.asarray(second)
    mask = np.ones(first.shape, bool) if mask is None else np.asarray(mask, bool)
    count = int(mask.sum())
    same = int((first == second)[mask].sum())
    return (same / count if count else math.nan), count


@dataclass(frozen=True)
class MapComparison:
    """Outcome maps of the kernel and of pymunk over one grid, and how far they agree.

    Attributes
    ----------
    kernel, pymunk : numpy.ndarray of int8, shape (ny, nx)
        Sides, -1 undecided; row i belongs to ``y_values[i]``.
    x_values, y_values : numpy.ndarray
        Cell centres of the grid axes (SI units of their parameters).
    pymunk_status : numpy.ndarray of uint8, shape (ny, nx)
        ``STATUS_NAMES`` codes of the pymunk rolls.
    pymunk_seconds : float
        CPU time of the pymunk rolls, s.
    dt : float
        pymunk's step, s.
    settings : PymunkSettings
        pymunk's solver settings.
    kernel_status : numpy.ndarray of uint8, shape (ny, nx)
        ``dice_sweep.physics.STATUS_NAMES`` codes of the kernel's rolls.
    kernel_counts : dict of str to numpy.ndarray of int32, shape (ny, nx)
        The kernel's event tallies, one map per ``dice_sweep.physics.COUNT_COLUMNS`` name.
    """

    kernel: np.ndarray
    pymunk: np.ndarray
    x_values: np.ndarray
    y_values: np.ndarray
    pymunk_status: np.ndarray
    pymunk_seconds: float
    dt: float
    settings: PymunkSettings
    kernel_status: np.ndarray
    kernel_counts: dict

    def agreement(self, width=None):
        """Share of pixels with the same side, over all pixels or (``width``) the settled ones.

        Parameters
        ----------
        width : int, optional
            Only pixels whose width x width neighbourhood in the kernel's map is one side
            (:func:`settled_mask`).

        Returns
        -------
        share : float
            In [0, 1]; NaN when no pixel qualifies.
        count : int
            Pixels compared.
        """
        return self.agreement_on(None if width is None else settled_mask(self.kernel, width))

    def agreement_on(self, mask=None):
        """(share, count) of pixels with the same side among those of ``mask`` (bool (ny, nx);
        None: all), as :func:`map_agreement` gives them."""
        return map_agreement(self.kernel, self.pymunk, mask)

    def rolls_per_second(self):
        """pymunk rolls per CPU second (it runs on one core)."""
        return self.kernel.size / self.pymunk_seconds


# Issue 4's like-for-like check: the rigid model without tangential restitution (pymunk has
# none), a Table-I-sized square (R = 1.9/sqrt(2) cm), beta_normal of Table I, low drops.
COMPARISON_CONFIG = f"""
[die]
sides = 4
circumradius = {0.019 / math.sqrt(2.0)!r}
[contact]
model = "rigid"
beta_normal = 0.2
beta_tangential = 0.0
friction = 0.5
[initial]
phi0 = 0.0
vx0 = 0.0
vy0 = 0.0
[integrator]
t_max = 5.0
[grid]
x = {{ param = "omega0", min = 0.0, max = 30.0, num = 48 }}
y = {{ param = "y0", min = 0.02, max = 0.08, num = 48 }}
"""


def comparison_config(num=48, overrides=()):
    """The config of issue 4's check (``COMPARISON_CONFIG``) on a num x num grid.

    Parameters
    ----------
    num : int
        Cells per grid axis.
    overrides : sequence of str
        ``KEY=VALUE`` overrides as in ``--set``, applied after ``num``.

    Returns
    -------
    dice_sweep.config.Config
    """
    return _config_on_grid(COMPARISON_CONFIG, "COMPARISON_CONFIG", num, overrides)


def _config_on_grid(text, name, num, overrides):
    """Parse config ``text`` (named ``name`` in errors) with a num x num grid, then ``overrides``."""
    return parse_config(text, name, [f"grid.x.num={num}", f"grid.y.num={num}", *overrides])


@dataclass(frozen=True)
class PymunkMap:
    """pymunk's outcome map over a config's grid (:func:`pymunk_map`).

    Attributes
    ----------
    outcome : numpy.ndarray of int8, shape (ny, nx)
        Sides, -1 undecided; row i belongs to the i-th value of the grid's y axis.
    status : numpy.ndarray of uint8, shape (ny, nx)
        ``STATUS_NAMES`` codes.
    seconds : float
        CPU time of the rolls, s.
    dt : float
        pymunk's step, s.
    """

    outcome: np.ndarray
    status: np.ndarray
    seconds: float
    dt: float


def grid_states(cfg):
    """Axis values xs, ys and the initial states of ``cfg``'s grid, shape (len(ys) * len(xs), 6),
    rows y slow and x fast, as the maps are stored."""
    from dice_sweep.mapper import initial_states

    xs, ys = cfg.grid.x.values(), cfg.grid.y.values()
    return xs, ys, initial_states(cfg, xs, ys)


def pymunk_map(cfg, *, dt=1e-4, settings=PymunkSettings()):
    """Roll every cell of ``cfg``'s grid in pymunk (:func:`pymunk_batch`, t_max of the config).

    Returns
    -------
    PymunkMap
    """
    xs, ys, states = grid_states(cfg)
    # CPU time of this process: the machine may be shared, and pymunk runs on one core
    start = time.process_time()
    reference = pymunk_batch(cfg, states, dt=dt, t_max=cfg.integrator.t_max, settings=settings)
    seconds = time.process_time() - start
    shape = (len(ys), len(xs))
    return PymunkMap(reference.outcome.reshape(shape), reference.status.reshape(shape), seconds, dt)


def compare_with_kernel(cfg, *, dt=1e-4, settings=PymunkSettings()):
    """Roll every cell of ``cfg``'s grid with the kernel and with pymunk.

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        Has a ``[grid]``; its ``contact.friction`` is pymunk's mu and ``integrator.t_max`` both
        simulators' time limit. For a like-for-like check use ``model = "rigid"`` with
        ``beta_tangential = 0``.
    dt, settings
        pymunk's step, s, and solver settings (:func:`pymunk_roll`).

    Returns
    -------
    MapComparison
    """
    from dice_sweep.mapper import Mapper
    from dice_sweep.physics.layout import COUNT_COLUMNS

    xs, ys, states = grid_states(cfg)
    shape = (len(ys), len(xs))
    kernel_outcome, kernel_status, kernel_counts, _ = Mapper.from_config(cfg).roll(states)
    reference = pymunk_map(cfg, dt=dt, settings=settings)
    return MapComparison(
        kernel=kernel_outcome.reshape(shape),
        pymunk=reference.outcome,
        x_values=xs,
        y_values=ys,
        pymunk_status=reference.status,
        pymunk_seconds=reference.seconds,
        dt=dt,
        settings=settings,
        kernel_status=kernel_status.reshape(shape),
        kernel_counts={name: kernel_counts[:, k].reshape(shape) for k, name in enumerate(COUNT_COLUMNS)},
    )


# --- flat impacts (issue 15) -----------------------------------------------------------------

# pymunk for the flat-impact maps (docs/validation.md, "Flat impacts"): 30 solver passes leave
# a flat landing of the hexagon with a spin of 1e-3 to 1e-2 rad/s (Gauss-Seidel takes the two
# contacts in turn), which tilts the die enough by its next landing for the map to change with
# the step; 100 passes leave below 1e-8 rad/s and a map that no longer changes with step or passes.
FLAT_SETTINGS = PymunkSettings(iterations=100)
FLAT_DT = 5e-5  # s; the maps agree with those at dt/2 on 99.8 to 100 % of their pixels

# Name of the kernel's count of impacts solved as simultaneous contacts, once it has one.
MULTI_CONTACTS = "multi_contacts"
# Without that count, two kernel impacts closer in time than this (x sqrt(R/g), 37 ns for the
# Table-I die) make one flat impact: the kernel without a two-contact law applies them in turn.
FLAT_IMPACT_TIME = 1e-6
# Two corners whose reach towards a surface differs by less than this (x R) meet it together.
FLAT_REACH = 1e-9


def flat_side_angle(sides, side=0):
    """Orientation phi0 (rad) with side ``side`` flat below the centre: -pi/2 - pi/n - 2 pi k/n.

    Side k joins corners k and k+1, at phi + 2 pi k/n and phi + 2 pi (k+1)/n; they sit at
    -pi/2 -+ pi/n, symmetric about the downward vertical, when phi takes this value.
    """
    return -0.5 * math.pi - math.pi / sides - 2.0 * math.pi * side / sides


# Issue 15's maps: issue 4's set-up thrown sideways without spin, y0 against vx0.
_FLAT_GRID = ("grid.x.param=vx0", "grid.x.min=-1.0", "grid.x.max=1.0", "grid.y.max=0.10", "initial.omega0=0.0")
# The wall case: a pentagon with side 2 vertical (phi0 = 0) thrown at the walls. Thrown to the
# left fast and high enough, it meets the left wall flat before it meets the table.
FLAT_WALL = ("die.sides=5", "contact.beta_normal=0.3", "contact.friction=0.4", "walls.separation=0.2")
# The flat landing: a die (the hexagon of the issue by default) dropped flat on side 0 without
# walls, so that every roll starts with a flat landing.
FLAT_LANDING = ("contact.beta_normal=0.5", "contact.friction=0.8")


def flat_wall_config(num=32, overrides=()):
    """Issue 15's wall map (``FLAT_WALL`` over issue 4's config) on a num x num grid, then
    ``overrides``."""
    return _config_on_grid(COMPARISON_CONFIG, "FLAT_WALL", num, (*_FLAT_GRID, *FLAT_WALL, *overrides))


def flat_landing_config(num=32, sides=6, overrides=()):
    """Issue 15's flat-landing map (``FLAT_LANDING`` over issue 4's config) for an n-gon
    dropped flat on side 0.

    Parameters
    ----------
    num : int
        Cells per grid axis.
    sides : int
        n; phi0 is :func:`flat_side_angle` (n, 0).
    overrides : sequence of str
        ``KEY=VALUE`` overrides as in ``--set``, applied last.

    Returns
    -------
    dice_sweep.config.Config
    """
    shape = (f"die.sides={sides}", f"initial.phi0={flat_side_angle(sides)!r}")
    return _config_on_grid(COMPARISON_CONFIG, "FLAT_LANDING", num, (*_FLAT_GRID, *FLAT_LANDING, *shape, *overrides))


def flat_impact_configs(num=32, overrides=()):
    """The maps of issue 15's check on num x num grids, ``overrides`` (``--set`` style) applied
    to each: ``"wall"`` (:func:`flat_wall_config`), ``"hexagon"`` and ``"square"``
    (:func:`flat_landing_config` with n = 6 and n = 4)."""
    return {
        "wall": flat_wall_config(num, overrides),
        "hexagon": flat_landing_config(num, 6, overrides),
        "square": flat_landing_config(num, 4, overrides),
    }


def first_contact_is_flat(cfg, states):
    """Whether the free flight of each state meets its first surface with a side flat against it.

    Geometry only, the same for any contact law: a die without spin keeps its orientation in
    flight, so its first contact is the surface (table or wall of ``cfg``) that its reach
    along that surface's normal meets first; it is flat when two corners share that reach
    (within ``FLAT_REACH`` R).

    Parameters
    ----------
    cfg : dice_sweep.config.Config or alike
        ``die.sides``, ``die.circumradius``, ``world.g``, ``walls.separation``.
    states : array_like, shape (N, 6)
        Initial states, columns ``STATE_COLUMNS`` (SI units).

    Returns
    -------
    numpy.ndarray of bool, shape (N,)
        False for a spinning start, and for one that never meets a surface.
    """
    states = np.atleast_2d(np.asarray(states, dtype=float))
    x, y, phi, vx, vy, omega = states.T
    sides, radius, g = cfg.die.sides, cfg.die.circumradius, cfg.world.g
    offsets = np.stack([corners(sides, radius, 0.0, 0.0, angle) for angle in phi])  # (N, n, 2)
    half = math.inf if cfg.walls.separation is None else 0.5 * cfg.walls.separation
    # each surface: reach of every corner towards it (N, n), and the time the die meets it
    down = -offsets[:, :, 1]
    drop = y - down.max(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        times = [(vy + np.sqrt(vy * vy + 2.0 * g * drop)) / g]
        reaches = [down]
        for sign in (-1.0, 1.0):  # the left wall, the right wall
            reach = sign * offsets[:, :, 0]
            gap = half - sign * x - reach.max(axis=1)
            times.append(np.where(sign * vx > 0.0, gap / (sign * vx), np.inf))
            reaches.append(reach)
    times, reaches = np.stack(times), np.stack(reaches)  # (3, N), (3, N, n)
    first = np.argmin(times, axis=0)
    rows = np.arange(len(states))
    reach = reaches[first, rows]  # (N, n)
    touching = (reach.max(axis=1)[:, None] - reach <= FLAT_REACH * radius).sum(axis=1)
    return (touching >= 2) & (omega == 0.0) & np.isfinite(times[first, rows])


def kernel_flat_impacts(cfg, comparison):
    """Pixels whose kernel roll had a flat impact: two corners meeting a surface at once.

    Uses the kernel's ``MULTI_CONTACTS`` count when the kernel has one. Otherwise rolls each
    pixel again with its path records, and counts two impacts less than ``FLAT_IMPACT_TIME``
    sqrt(R/g) apart (a kernel that applies two single-corner impulses in turn records both
    at the same time).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        The config of ``comparison``.
    comparison : MapComparison
        From :func:`compare_with_kernel` on ``cfg``.

    Returns
    -------
    mask : numpy.ndarray of bool, shape (ny, nx)
    criterion : str
        Which of the two criteria gave the mask.
    """
    if MULTI_CONTACTS in comparison.kernel_counts:
        return comparison.kernel_counts[MULTI_CONTACTS] > 0, f"the kernel's {MULTI_CONTACTS} count > 0"
    from dice_sweep.physics.layout import EVENT_IMPACT, REC_EVENT, REC_KIND, REC_T, SEG_SLIDE
    from dice_sweep.roll import roll_config

    tolerance = FLAT_IMPACT_TIME * math.sqrt(cfg.die.circumradius / cfg.world.g)
    _, _, states = grid_states(cfg)
    flat = np.zeros(len(states), bool)
    for index, state in enumerate(states):
        records = roll_config(cfg, state).records
        # impact rows, but not the end of a slide on a side (recorded as an impact too)
        after_slide = np.r_[False, records[:-1, REC_KIND] == SEG_SLIDE]
        times = records[(records[:, REC_EVENT] == EVENT_IMPACT) & ~after_slide, REC_T]
        flat[index] = bool((np.diff(times) <= tolerance).any())
    criterion = f"two kernel impacts within {tolerance * 1e9:.0f} ns (the kernel has no {MULTI_CONTACTS} count)"
    return flat.reshape(comparison.kernel.shape), criterion
