"""Impacts in a measured track: where they are, and the motion just before and just after.

Shared by :mod:`dice_sweep.measured.tracks` (the sign of the angle, from the first impacts)
and :mod:`dice_sweep.measured.calibrate` (restitution coefficients). Everything works on plain
arrays in the model's conventions (docs/calibration.md states the rules):

* an impact is a local minimum of the lowest corner's height, below ``CONTACT_HEIGHT`` R above
  the table, reached while that corner comes down faster than ``APPROACH_SPEED`` sqrt(g R)
  over the two frames before;
* on each side of it, the usable frames up to the neighbouring impact (at most ``FIT_FRAMES``,
  the impact's own frame left out) get a free-flight fit: x and phi linear in t, y a parabola
  of curvature -g;
* each side's fit is followed to where its own lowest corner meets the table, and the velocities
  are taken there. Frames dropped during the impact (the file's times after it too early) shift
  the after-side's contact time, not its velocities; the shift is reported as ``gap_frames``.
"""

import math
from dataclasses import dataclass

import numpy as np

from dice_sweep.geometry import DOWN, corner_angles, support

__all__ = ["SideFit", "Impact", "find_impacts", "fit_impact", "track_impacts", "lowest_height", "touching_corner", "landing_tilt", "rest_pose", "table_level"]

CONTACT_HEIGHT = 0.1  # R: a lower minimum of the lowest corner may be an impact
APPROACH_SPEED = 0.2  # sqrt(g R): slower descents are rocking, or noise of a die at rest
FIT_FRAMES = 5  # frames at most on each side of an impact
MIN_FIT_FRAMES = 3  # fewer frames leave no check on a two-parameter fit
MAX_GAP_FRAMES = 16  # frames an impact may have dropped (the largest seen in flight is 13)
COARSE_SAMPLES = 8  # samples per frame when following a fit to the table ...
FINE_SAMPLES = 65  # ... then across two coarse spacings around the crossing
REST_FRAMES = 10  # last frames of a track that must be still for it to count as at rest ...
REST_TIME = 0.1  # s ... and at least this long (a die at rest stays still for good)
REST_ANGLE_RANGE = math.radians(1.0)  # rad, largest spread of the angle over those frames
REST_MOTION_RANGE = 0.02  # circumradii, largest spread of x and y over those frames


@dataclass(frozen=True)
class SideFit:
    """Free flight on one side of an impact, followed to the table.

    Attributes
    ----------
    t_contact : float
        s, in the file's time base, where this side's lowest corner meets the table (its
        closest approach if it does not reach it).
    state : numpy.ndarray, shape (6,)
        (x, y, phi, vx, vy, omega) of the centre at ``t_contact``, SI.
    frames : int
        Frames fitted.
    rms : float
        Root-mean-square pose residual of the fit, sqrt(dx^2 + dy^2 + (R dphi)^2), m.
    touched : bool
        Whether the fitted lowest corner reaches the table from above, between the fitted
        frames and the impact (False also when it is below the table at those frames already:
        a sustained contact).
    """

    t_contact: float
    state: np.ndarray
    frames: int
    rms: float
    touched: bool


@dataclass(frozen=True)
class Impact:
    """One impact: the frame it was found at, the fits on both sides and the touching corner.

    Attributes
    ----------
    frame : int
        Index of the frame with the lowest corner at its minimum.
    before, after : SideFit
        Motion up to and from the table.
    corner : numpy.ndarray, shape (2,)
        The touching corner seen from the centre at contact (m), from the before-side pose.
    gap_frames : float
        (before.t_contact - after.t_contact) times the frame rate: frames the file dropped
        during the impact (about 0 when none were). Below 0 the contact lasted: rounded corners,
        a compliant table, a second corner or a sustained contact.
    mismatch : float
        Distance between the two sides' poses at their contact times,
        sqrt(dx^2 + dy^2 + (R dphi)^2) with dphi modulo 2 pi / n, m: large when the sides do not
        describe one impact.
    """

    frame: int
    before: SideFit
    after: SideFit
    corner: np.ndarray
    gap_frames: float
    mismatch: float


def lowest_height(sides, circumradius, y, phi, table=0.0):
    """Height of the lowest corner above the table level ``table`` (m); broadcasts."""
    return np.asarray(y) - support(sides, circumradius, phi, DOWN) - table


def rest_pose(x, y, phi, usable, circumradius, t=None):
    """Mean (x, y, phi) over the last frames if the track ends at rest, else None.

    At rest means: the last ``REST_FRAMES`` usable frames, and at least the last ``REST_TIME``
    when the times ``t`` are given, end the track (but for two frames) and spread by less than
    ``REST_MOTION_RANGE`` R in y and ``REST_ANGLE_RANGE`` in angle. (At 500 Hz ten frames
    are 20 ms, over which a die still bouncing at a few cm/s looked still.)
    """
    index = np.flatnonzero(usable)
    if index.size < REST_FRAMES or index[-1] < x.size - 3:  # a track may end on two missing frames
        return None
    count = REST_FRAMES
    if t is not None:
        count = max(count, int(np.count_nonzero(t[index] >= t[index[-1]] - REST_TIME)))
    last = index[-count:]
    # still: neither a drift (the change of a fitted line over the window) nor a scatter
    # beyond the ranges; with noise, the range of 25 frames exceeded 1 deg at 0.3 deg a frame
    # (x may still change: a die lying flat may slide on a slippery table)
    frames = np.arange(last.size, dtype=float)
    still = True
    for values, limit in ((y[last], REST_MOTION_RANGE * circumradius), (phi[last], REST_ANGLE_RANGE)):
        slope, intercept = np.polyfit(frames, values, 1)
        scatter = np.std(values - (slope * frames + intercept))
        still = still and abs(slope) * frames[-1] < limit and scatter < limit
    return (float(np.mean(x[last])), float(np.mean(y[last])), float(np.mean(phi[last]))) if still else None


def table_level(rest_poses, *, sides, circumradius):
    """Height of the table in the tracks' frame (m): median lowest-corner height at rest.

    ``rest_poses`` are (x, y, phi) of dice at rest (phi in the model's convention, or any
    angle whose flat pose is that of the model: the height does not depend on the sign).
    Returns 0 when there are none.
    """
    if not rest_poses:
        return 0.0
    poses = np.array(rest_poses)
    return float(np.median(lowest_height(sides, circumradius, poses[:, 1], poses[:, 2])))


def find_impacts(t, y, phi, usable, *, sides, circumradius, table=0.0, g=9.81):
    """Frames at which a corner hits the table.

    Parameters
    ----------
    t, y, phi : ndarray
        Times (s), heights of the centre (m) and angles (rad, model convention) of one track.
    usable : ndarray of bool
        Frames to look at (complete poses, no glitches).
    sides, circumradius : int, float
        The die.
    table : float
        Height of the table in the track's frame, m.
    g : float
        m/s^2, sets the speed scale of ``APPROACH_SPEED``.

    Returns
    -------
    list of int
        Frame indices, ascending.
    """
    index = np.flatnonzero(usable)
    if index.size < 3:
        return []
    height = lowest_height(sides, circumradius, y[index], phi[index], table)
    min_speed = APPROACH_SPEED * math.sqrt(g * circumradius)
    inner = np.arange(2, index.size - 1)
    # over two frames, so that the tracker's noise of a die at rest does not look like impacts
    descent = (height[inner - 2] - height[inner]) / (t[index[inner]] - t[index[inner - 2]])
    found = (
        (height[inner] < CONTACT_HEIGHT * circumradius)
        & (height[inner] <= height[inner - 1])
        & (height[inner] < height[inner + 1])
        & (descent > min_speed)
    )
    return [int(i) for i in index[inner[found]]]


def _flight_fit(t, x, y, phi, frames, t_ref, circumradius, g):
    """Least-squares free flight through ``frames``: coefficients about ``t_ref`` and rms (m)."""
    dt = t[frames] - t_ref
    design = np.column_stack((np.ones_like(dt), dt))
    fall = 0.5 * g * dt**2
    targets = np.column_stack((x[frames], y[frames] + fall, phi[frames]))
    coeffs, *_ = np.linalg.lstsq(design, targets, rcond=None)
    residual = targets - design @ coeffs
    residual[:, 2] *= circumradius
    rms = float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))
    return coeffs, rms


def _state(coeffs, t_ref, time, g):
    """(x, y, phi, vx, vy, omega) on a fitted flight at ``time`` (scalar or array)."""
    dt = np.asarray(time) - t_ref
    x = coeffs[0, 0] + coeffs[1, 0] * dt
    y = coeffs[0, 1] + coeffs[1, 1] * dt - 0.5 * g * dt**2
    phi = coeffs[0, 2] + coeffs[1, 2] * dt
    vy = coeffs[1, 1] - g * dt
    return np.array([x, y, phi, np.broadcast_to(coeffs[1, 0], dt.shape), vy, np.broadcast_to(coeffs[1, 2], dt.shape)])


def _side_fit(t, x, y, phi, frames, window, *, sides, circumradius, table, g, forward):
    """Fit ``frames`` and follow the flight over ``window`` (s, s) to the table.

    ``forward``: the first crossing from the window's start (the side before the impact);
    otherwise the last crossing before the window's end (the side after it).
    """
    t_ref = t[frames[-1]] if forward else t[frames[0]]
    coeffs, rms = _flight_fit(t, x, y, phi, frames, t_ref, circumradius, g)
    frame_time = np.median(np.diff(t[frames]))
    coarse = np.linspace(window[0], window[1], max(int(round((window[1] - window[0]) / frame_time * COARSE_SAMPLES)), 2))
    hit, touched = _touch_time(coeffs, t_ref, coarse, forward, sides, circumradius, table, g)
    spacing = coarse[1] - coarse[0]
    hit, _ = _touch_time(coeffs, t_ref, np.linspace(hit - spacing, hit + spacing, FINE_SAMPLES), forward, sides, circumradius, table, g)
    return SideFit(t_contact=hit, state=_state(coeffs, t_ref, hit, g).astype(float), frames=int(frames.size), rms=rms, touched=touched)


def _touch_time(coeffs, t_ref, times, forward, sides, circumradius, table, g):
    """Among ``times``, the first (``forward``) or last sample with the fitted lowest corner at or
    below the table, and whether the flight reaches the table there from above; the closest
    approach and False if it never does."""
    path = _state(coeffs, t_ref, times, g)
    height = lowest_height(sides, circumradius, path[1], path[2], table)
    below = np.flatnonzero(height <= 0.0)
    if below.size == 0:
        return float(times[np.argmin(height)]), False
    pick = below[0] if forward else below[-1]
    # already below at the fitted frames' end: that side is in contact, not in flight
    return float(times[pick]), bool(pick != (0 if forward else times.size - 1))


def landing_tilt(sides, phi):
    """Angle between the table and the lower side next to the lowest corner, rad.

    0 for a die landing flat on a side, pi/n when the lowest corner points straight down.
    """
    offset = (phi - DOWN + math.pi / sides) % (2.0 * math.pi / sides) - math.pi / sides
    return math.pi / sides - abs(offset)


def touching_corner(sides, circumradius, phi):
    """The lowest corner seen from the centre, (2,) m, for a die at angle ``phi``."""
    angles = corner_angles(sides, phi)
    lowest = angles[np.argmin(np.sin(angles))]
    return circumradius * np.array([math.cos(lowest), math.sin(lowest)])


def fit_impact(t, x, y, phi, usable, frame, *, previous=None, following=None, sides, circumradius, table=0.0, g=9.81):
    """Free-flight fits on both sides of the impact at ``frame``, each followed to the table.

    Parameters
    ----------
    t, x, y, phi : ndarray
        One track, SI, model convention.
    usable : ndarray of bool
        Frames that may be fitted.
    frame : int
        The impact (from :func:`find_impacts`).
    previous, following : int, optional
        Neighbouring impacts: the fits do not reach past them.
    sides, circumradius, table, g
        As in :func:`find_impacts`.

    Returns
    -------
    Impact or None
        None when a side has fewer than ``MIN_FIT_FRAMES`` usable frames.
    """
    lo = -1 if previous is None else previous
    hi = t.size if following is None else following
    frames = np.flatnonzero(usable)
    before = frames[(frames > lo) & (frames < frame)][-FIT_FRAMES:]
    after = frames[(frames > frame) & (frames < hi)][:FIT_FRAMES]
    if before.size < MIN_FIT_FRAMES or after.size < MIN_FIT_FRAMES:
        return None
    frame_time = float(np.median(np.diff(t)))
    reach = (MAX_GAP_FRAMES + 1) * frame_time
    common = {"sides": sides, "circumradius": circumradius, "table": table, "g": g}
    side_before = _side_fit(t, x, y, phi, before, (t[before[-1]], t[before[-1]] + reach), forward=True, **common)
    side_after = _side_fit(t, x, y, phi, after, (t[after[0]] - reach, t[after[0]]), forward=False, **common)
    step = side_before.state[:3] - side_after.state[:3]
    # a tracker that cannot tell the corners apart may relabel them: compare angles mod 2 pi / n
    period = 2.0 * math.pi / sides
    step[2] = circumradius * ((step[2] + 0.5 * period) % period - 0.5 * period)
    return Impact(
        frame=int(frame),
        before=side_before,
        after=side_after,
        corner=touching_corner(sides, circumradius, side_before.state[2]),
        gap_frames=(side_before.t_contact - side_after.t_contact) / frame_time,
        mismatch=float(np.linalg.norm(step)),
    )


def track_impacts(t, x, y, phi, usable, *, first_only=False, **die):
    """The impacts of one track, in order, fitted where they can be.

    ``die`` holds ``sides``, ``circumradius`` and optionally ``table`` and ``g``, as for
    :func:`fit_impact`. ``first_only``: look at the first impact found, nothing else.
    Returns a list of (index among the impacts found, Impact or None when a side has too few
    frames).
    """
    found = find_impacts(t, y, phi, usable, **die)
    fitted = []
    for k, frame in enumerate(found[:1] if first_only else found):
        previous = found[k - 1] if k > 0 else None
        following = found[k + 1] if k + 1 < len(found) else None
        fitted.append((k, fit_impact(t, x, y, phi, usable, frame, previous=previous, following=following, **die)))
    return fitted
