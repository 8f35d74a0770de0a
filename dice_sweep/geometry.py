"""Geometry of a regular n-gon die (Smith 2014, section II and Fig. 7).

Conventions, shared with the kernel and the plots:

* corner ``k`` (``k = 0 .. n-1``) sits at angle ``phi + 2 pi k / n`` from the centre, at the
  circumradius ``R``;
* side ``k`` joins corners ``k`` and ``k + 1`` (mod n), so side 0 lies between the corners at
  ``phi`` and ``phi + 2 pi / n`` and the sides are numbered counterclockwise (paper, Fig. 7);
* with rounded corners (``[effects] corner_radius`` r > 0) the die keeps its apothem and is a
  core polygon of circumradius :func:`core_circumradius` grown by a disk of radius r: corner k
  is an arc of radius r centred at the core's corner k (docs/physics.md, "Rounded corners").

All lengths are in metres, angles in radians. Functions taking ``y`` or ``phi`` accept numpy
arrays and broadcast them.
"""

import math

import numpy as np

__all__ = [
    "apothem",
    "side_length",
    "inertia_ratio",
    "moment_of_inertia",
    "corner_angles",
    "corners",
    "core_circumradius",
    "outline",
    "support",
    "lowest_corner_height",
    "side_below",
    "clear_of_surfaces",
]

DOWN = -0.5 * np.pi  # angle of the vertical ray pointing down from the centre, rad


def _central_angle(sides):
    """Angle 2 pi / n between neighbouring corners, seen from the centre (rad)."""
    return 2.0 * np.pi / sides


def apothem(sides, circumradius):
    """Distance from the centre to the middle of a side, A = R cos(pi/n) (paper eq. 1).

    Parameters
    ----------
    sides, circumradius : int, float
        The die: n >= 3 sides inscribed in a circle of radius R (m).

    Returns
    -------
    apothem : float
        A, m: the height of the centre when the die lies flat on a side.
    """
    return circumradius * np.cos(np.pi / sides)


def side_length(sides, circumradius):
    """Length of one side, S = 2 R sin(pi/n) (paper eq. 2).

    Parameters
    ----------
    sides : int
        n >= 3.
    circumradius : float
        R, m: the distance from the centre to each corner.

    Returns
    -------
    side : float
        S, m.
    """
    return 2.0 * circumradius * np.sin(np.pi / sides)


def inertia_ratio(sides):
    """Dimensionless moment of inertia alpha = I / (M R^2) of a uniform n-gon plate.

    alpha = sin^2(pi/n) / 6 + cos^2(pi/n) / 2 (paper eq. 25): 1/4 for a triangle, 1/3 for a
    square, tending to 1/2 (a disc) as n grows.

    Parameters
    ----------
    sides : int or array_like
        Number of sides n (>= 3).

    Returns
    -------
    alpha : float or ndarray
        Dimensionless.
    """
    half_angle = np.pi / np.asarray(sides, dtype=float)
    return np.sin(half_angle) ** 2 / 6.0 + np.cos(half_angle) ** 2 / 2.0


def moment_of_inertia(sides, circumradius, mass):
    """Moment of inertia about the centre, I = alpha M R^2 (paper eq. 25).

    Parameters
    ----------
    sides, circumradius : int, float
        Shape of the plate: n >= 3 sides, circumradius R in m.
    mass : float
        M, kg (uniformly spread over the plate).

    Returns
    -------
    inertia : float
        I, kg m^2.
    """
    return inertia_ratio(sides) * mass * circumradius**2


def corner_angles(sides, phi):
    """Angles of the corners from the centre: corner k at phi + 2 pi k / n.

    Parameters
    ----------
    sides : int
        n >= 3.
    phi : float
        Orientation of the die: the angle of corner 0, rad.

    Returns
    -------
    angles : ndarray, shape (n,)
        Corner angles, rad (not reduced modulo 2 pi).
    """
    return phi + _central_angle(sides) * np.arange(sides)


def corners(sides, circumradius, x, y, phi):
    """Positions of the corners of a die centred at (x, y) with orientation phi.

    Parameters
    ----------
    sides, circumradius : int, float
        The die: n >= 3 corners on a circle of radius R (m).
    x, y : float
        Position of the centre, m.
    phi : float
        Angle of corner 0, rad.

    Returns
    -------
    points : ndarray, shape (n, 2)
        Row k holds (x, y) of corner k, m.
    """
    angles = corner_angles(sides, phi)
    return np.column_stack((x + circumradius * np.cos(angles), y + circumradius * np.sin(angles)))


def core_circumradius(sides, circumradius, corner_radius):
    """Circumradius Rc = (a - r) / cos(pi/n) of the core polygon of a die whose corners are
    rounded to r and whose apothem a = R cos(pi/n) is kept: the arc centres' distance from
    the geometric centre, m (the kernel's corner block, physics/params.py, holds them).

    Parameters
    ----------
    sides, circumradius : int, float
        The sharp die: n >= 3 sides, circumradius R in m.
    corner_radius : float
        r, m, in [0, a).

    Returns
    -------
    core : float
        Rc, m.
    """
    # math, not numpy: pack_params calls this, and the kernel's numbers must not move
    c = math.cos(math.pi / sides)
    return (circumradius * c - corner_radius) / c


def _arc_centre_radius(sides, circumradius, corner_radius):
    """The core's circumradius, or R itself (untouched, bit for bit) for a sharp die."""
    return circumradius if corner_radius == 0.0 else core_circumradius(sides, circumradius, corner_radius)


def outline(sides, circumradius, x, y, phi, corner_radius=0.0, max_step=np.pi / 36):
    """Points along the outline of a die centred at (x, y), for drawing it.

    Each corner is an arc of radius ``corner_radius`` about the core's corner, from the
    normal of the side before it to that of the side after it (angles phi + 2 pi k/n -+ pi/n);
    straight sides join consecutive arcs. A sharp die (r = 0) is its corners.

    Parameters
    ----------
    sides, circumradius : int, float
        The die: n >= 3 sides, circumradius R in m.
    x, y : float
        Position of the geometric centre, m.
    phi : float
        Angle of corner 0, rad.
    corner_radius : float
        r, m, in [0, R cos(pi/n)).
    max_step : float
        Largest angle between neighbouring points of an arc, rad.

    Returns
    -------
    arcs : ndarray, shape (n, m, 2)
        ``arcs[k]`` holds (x, y) of m points along corner k's arc, counterclockwise (m = 1,
        the corner itself, when r = 0); side k runs from ``arcs[k, -1]`` to ``arcs[k + 1, 0]``.
        ``arcs.reshape(-1, 2)`` is the closed outline.
    """
    if corner_radius == 0.0:
        return corners(sides, circumradius, x, y, phi)[:, None, :]
    half = np.pi / sides
    count = max(2, math.ceil(2.0 * half / max_step) + 1)
    centres = corners(sides, core_circumradius(sides, circumradius, corner_radius), x, y, phi)
    angles = corner_angles(sides, phi)[:, None] + np.linspace(-half, half, count)
    return np.stack((centres[:, :1] + corner_radius * np.cos(angles), centres[:, 1:] + corner_radius * np.sin(angles)), axis=-1)


def support(sides, circumradius, phi, direction, corner_radius=0.0):
    """How far the die reaches from its centre along a direction (its support function).

    This is the largest projection of a corner offset onto the unit vector at angle
    ``direction``: ``R cos(d)`` with ``d`` the angle from that direction to the nearest corner.
    With rounded corners it is the arc centres' reach plus r, ``Rc cos(d) + r`` (Rc:
    :func:`core_circumradius`), where the kernel finds a surface touched.
    The die's lowest point is ``y - support(..., -pi/2)``, its right-most ``x + support(..., 0)``.

    Parameters
    ----------
    sides : int
        n >= 3.
    circumradius : float
        R, m.
    phi : float or array_like
        Orientation (angle of corner 0), rad.
    direction : float or array_like
        Angle of the direction, rad (0: +x, pi/2: +y).
    corner_radius : float
        r, m (0: sharp corners).

    Returns
    -------
    reach : float or ndarray
        Reach along the direction, m, between the apothem and R; broadcast over phi, direction.
    """
    spacing = _central_angle(sides)
    offset = np.mod(np.asarray(direction) - np.asarray(phi), spacing)
    nearest = np.minimum(offset, spacing - offset)
    # + 0.0 leaves a sharp die's reach as it was, bit for bit
    return _arc_centre_radius(sides, circumradius, corner_radius) * np.cos(nearest) + corner_radius


def lowest_corner_height(sides, circumradius, y, phi):
    """Height of the lowest corner of a die whose centre is at height y.

    Parameters
    ----------
    sides, circumradius : int, float
        The die: n >= 3 sides, circumradius R in m.
    y : float or array_like
        Height of the centre above the table, m.
    phi : float or array_like
        Angle of corner 0, rad.

    Returns
    -------
    height : float or ndarray
        Height of the lowest corner, m (negative: inside the table); broadcast over y, phi.
    """
    return np.asarray(y) - support(sides, circumradius, phi, DOWN)


def side_below(sides, phi):
    """Index of the side crossed by the vertical ray pointing down from the centre.

    Side k spans the corner angles [phi + 2 pi k / n, phi + 2 pi (k+1) / n). This is the side
    the die rests on once it can no longer pass over a corner. Turning the die by +2 pi / n
    lowers the index by one (mod n): the ray then meets the side before.

    Parameters
    ----------
    sides : int
        n >= 3.
    phi : float or array_like
        Orientation of the die (angle of corner 0), rad.

    Returns
    -------
    side : int or ndarray of int
        Side index in 0 .. n-1.
    """
    turns = np.mod(DOWN - np.asarray(phi, dtype=float), 2.0 * np.pi) / _central_angle(sides)
    # mod and rounding can land exactly on n at the last corner: wrap it to side 0
    index = np.floor(turns).astype(np.int64) % sides
    return index if index.ndim else int(index)


def clear_of_surfaces(sides, circumradius, separation, states, corner_radius=0.0):
    """bool (N,): starts (rows x, y, phi, ...) with no part of the die inside the table, nor
    inside a wall when ``separation`` (m) is not None: the die's reach along each surface's
    normal (:func:`support`, rounded at ``corner_radius`` m) fits in the room its centre leaves.
    The config checks its own starts the same way (with a round-off tolerance, to name the
    value that fails)."""
    states = np.asarray(states, dtype=float)
    x, y, phi = states[:, 0], states[:, 1], states[:, 2]

    def reach(direction):
        return support(sides, circumradius, phi, direction, corner_radius)

    clear = y >= reach(DOWN)
    if separation is not None:
        half = 0.5 * separation
        clear &= (x + reach(0.0) <= half) & (x - reach(np.pi) >= -half)
    return clear
