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
    """

    kernel: np.ndarray
    pymunk: np.ndarray
    x_values: np.ndarray
    y_values: np.ndarray
    pymunk_status: np.ndarray
    pymunk_seconds: float
    dt: float
    settings: PymunkSettings

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
        mask = np.ones(self.kernel.shape, bool) if width is None else settled_mask(self.kernel, width)
        count = int(mask.sum())
        same = int((self.kernel == self.pymunk)[mask].sum())
        return (same / count if count else math.nan), count

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
    return parse_config(COMPARISON_CONFIG, "COMPARISON_CONFIG", [f"grid.x.num={num}", f"grid.y.num={num}", *overrides])


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
    from dice_sweep.sweep import SweepJob, initial_states  # the numba kernel: only needed here

    job = SweepJob.from_config(cfg)
    states = initial_states(cfg, job.xs, job.ys)
    shape = (len(job.ys), len(job.xs))
    kernel_outcome = job.roll(states)[0]
    # CPU time of this process: the machine may be shared, and pymunk runs on one core
    start = time.process_time()
    reference = pymunk_batch(cfg, states, dt=dt, t_max=cfg.integrator.t_max, settings=settings)
    seconds = time.process_time() - start
    return MapComparison(
        kernel=kernel_outcome.reshape(shape),
        pymunk=reference.outcome.reshape(shape),
        x_values=job.xs,
        y_values=job.ys,
        pymunk_status=reference.status.reshape(shape),
        pymunk_seconds=seconds,
        dt=dt,
        settings=settings,
    )
