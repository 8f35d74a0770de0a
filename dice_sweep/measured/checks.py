"""Measured data checked before the work (issue 30, item 5): units and conventions from the
tracks themselves, before any fitting.

A file in mm, an angle in degrees, a wrong frame rate, the drops of another die or an angle
whose zero is not the model's ran a fit to the end with numbers that mean nothing (or died
late: "needs more than 4096 kernel records" on real drops read with their own angle). Each
check here measures one quantity from the data, with a 95 % interval over its independent
units (tracks or impacts), and compares it with what the config says it must be.
docs/measured_method.md ("Checks before the work") gives the thresholds and their calibration
on clean drops of the independent generator and on the real drops
(``python scripts/checks_calibration.py``).

The free flights are found here without the config (its g, its die and its angle are what is
checked): a quadratic in t of each of x, y and phi grown from a seed while the next frames stay
within ``FLIGHT_SIGMAS`` of its prediction, the track's own noise
(:func:`dice_sweep.measured.flights.difference_noise`: third differences, in any unit) as the
scale. Two flights a few frames apart whose vertical velocity turns upwards meet at an
*impact*, at the time where their fitted positions cross.

The checks, in the order they are reported:

``gravity``
    The vertical acceleration of each track's flights (their fitted curvature, inverse-variance
    mean over the track) against the config's g (times a declared tracking.length_scale, over
    tracking.time_scale^2). Positions in mm give 1000 g; a frame rate off by a factor k, g / k^2.
``angle_unit``
    At an impact through one point r within R of the centre, I dw = M r x dv (any contact law),
    so kappa = alpha R |dw| / |dv| <= 1 (alpha = I / M R^2, eq. 25). The median kappa of the
    impacts: an angle in degrees gives 57 times its value in rad.
``angle_wrap``
    The share of tracks whose angle jumps by a whole turn of 2 pi / n between two frames and
    stays (an angle wrapped into one side's range; the loader undoes jumps of 135 deg or more).
``rest_height``, ``rest_angle``
    Dice that end at rest (:func:`dice_sweep.measured.impacts.rest_pose`) lie on a side: the
    centre at the apothem R cos(pi/n), corner 0 at the flat pose modulo 2 pi / n.
``contact_height``, ``contact_share``
    At an impact the die's lowest point (the config's die at the model's angle) is on the
    table: y - R cos(d) = 0 (d: the angle from straight down to the nearest corner). The median
    of that height over the impacts (a table not at y = 0, another circumradius), and the share
    of impacts more than ``CONTACT_OFF`` R off (another die, an angle zero off by part of a
    side).

A check whose interval lies wholly beyond its error threshold raises one line (exit 2 from the
CLI), naming the file, the check, the value with its interval and what was expected; one
beyond its warning threshold, or a quantity no check could decide, gives a warning line.
``--no-check-units`` (:func:`settings`) skips them.
"""

import contextlib
import contextvars
import math
import sys
from dataclasses import dataclass, field

import numpy as np

from dice_sweep.errors import DiceSweepError
from dice_sweep.geometry import DOWN, apothem, inertia_ratio, support
from dice_sweep.measured.flights import difference_noise
from dice_sweep.measured.impacts import rest_pose

__all__ = ["Evidence", "Finding", "measure", "judge", "check_measured", "settings"]

# --- flights found without the config ------------------------------------------------------
SEED_FRAMES = 6  # usable frames of a flight's first fit
MIN_FLIGHT_FRAMES = 8  # usable frames a flight needs to give a curvature
FLIGHT_SIGMAS = 5.0  # a frame more than this many noise sigmas off the prediction ends a flight ...
CONFIRM_FRAMES = 2  # ... unless the next frames fit (then it is a glitch, skipped)
# the third differences see part of a tracker's correlated errors only (real drops: ballistic
# windows scatter 1.3 to 1.5 times as much, dice_sweep.measured.flights.WINDOW_EXCESS)
NOISE_EXCESS = 1.5
IMPACT_GAP_FRAMES = 6  # frames at most between two flights that meet at one impact
MIN_DV_SIGMAS = 10.0  # an impact's change of vertical velocity must be this many of its sigmas
MIN_CURVATURE_SIGMAS = 10.0  # a flight measures g when its curvature is this many of its sigmas ...
MIN_FLIGHT_RISE = 0.05  # ... and it rises or falls by this share of its track's height range
MAX_TRACKS = 200  # tracks measured, evenly spread over the file (the 500 real drops: 1.1 s instead of 4.7 s)

# --- the checks' numbers (docs/measured_method.md, "Checks before the work") -----------------
CONFIDENCE = 0.95
MIN_TRACKS = 5  # tracks with a measured flight (or at rest) a check needs to decide
MIN_IMPACTS = 8
GRAVITY_ERROR = 1.5  # factor: measured g outside [g / 1.5, 1.5 g] (the whole interval) ...
GRAVITY_WARN = 1.15  # ... an error; outside [g / 1.15, 1.15 g], a warning
KAPPA_ERROR = 2.0  # median alpha R |dw| / |dv| at impacts above this: not rad (the bound is 1)
KAPPA_WARN = 1.2
CONTACT_ERROR = 0.1  # R: median height of the lowest point at impacts off y = 0 by more: an error ...
CONTACT_WARN = 0.03  # ... by this much: a warning
CONTACT_OFF = 0.1  # R: an impact whose lowest point is this far off the table is off ...
CONTACT_SHARE_ERROR = 0.15  # ... and a share of such impacts above this is an error
CONTACT_SHARE_WARN = 0.06
REST_HEIGHT_ERROR = 0.2  # relative: rest height off the apothem by more than this share: an error ...
REST_HEIGHT_WARN = 0.1  # ... by this share: a warning (the real drops rest 5 % above it)
REST_ANGLE_ERROR = 0.5  # of pi / n (half the angle between corners): |rest angle - flat pose| beyond this ...
REST_ANGLE_WARN = 0.15
WRAP_TOLERANCE = 0.15  # rad: a step this close to a whole turn of 2 pi / n beyond the local motion is a wrap
WRAP_ERROR = 0.15  # share of tracks with a wrap
WRAP_WARN = 0.05


# --- settings (the CLI's --no-check-units and its warning line) -------------------------------

_SETTINGS = contextvars.ContextVar("dice_sweep_measured_checks", default=(True, None))


@contextlib.contextmanager
def settings(enabled=True, warn=None):
    """Within the block, :func:`check_measured` runs the checks (``enabled``) and says its
    warnings through ``warn(line)`` (default: a ``warning: ...`` line on stderr)."""
    token = _SETTINGS.set((bool(enabled), warn))
    try:
        yield
    finally:
        _SETTINGS.reset(token)


def _default_warn(line):
    print(f"warning: {line}", file=sys.stderr)


# --- statistics ------------------------------------------------------------------------------


def median_interval(values, confidence=CONFIDENCE):
    """Median of independent values and its distribution-free interval (order statistics of
    the binomial, normal approximation): (median, low, high); NaNs for no values."""
    v = np.sort(np.asarray(values, dtype=float)[np.isfinite(values)])
    n = v.size
    if n == 0:
        return math.nan, math.nan, math.nan
    half = 0.5 * _z(confidence) * math.sqrt(n)
    lo = max(int(math.floor(0.5 * n - half)), 0)
    hi = min(int(math.ceil(0.5 * n + half)), n - 1)
    return float(np.median(v)), float(v[lo]), float(v[hi])


def _z(confidence):
    from statistics import NormalDist

    return NormalDist().inv_cdf(0.5 + 0.5 * confidence)


# --- flights and impacts without the config --------------------------------------------------


@dataclass(frozen=True)
class _Flight:
    t0: float  # s, time origin of the fit
    first: float  # s, first and last fitted frame
    last: float
    coef: np.ndarray  # (3 coefficients c0 + c1 u + c2 u^2, 3 coordinates x, y, phi); u = t - t0
    cov: np.ndarray  # (3, 3) per unit variance, of (c0, c1, c2)
    sigma: np.ndarray  # (3,) noise of x, y, phi
    frames: int

    def at(self, t):
        u = np.asarray(t, dtype=float) - self.t0
        return self.coef[0] + np.multiply.outer(u, self.coef[1]) + np.multiply.outer(u * u, self.coef[2])

    def velocity(self, t):
        u = float(t) - self.t0
        return self.coef[1] + 2.0 * u * self.coef[2]

    def velocity_sigma(self, t):
        """Standard error of each velocity coordinate at ``t``."""
        u = float(t) - self.t0
        grad = np.array([0.0, 1.0, 2.0 * u])
        return self.sigma * math.sqrt(max(grad @ self.cov @ grad, 0.0))

    @property
    def acceleration(self):
        return 2.0 * self.coef[2]

    @property
    def acceleration_sigma(self):
        return 2.0 * self.sigma * math.sqrt(max(self.cov[2, 2], 0.0))


def _fit(u, values):
    """Least-squares quadratic of each column over times ``u``: (coef (3, 3), cov (3, 3))."""
    basis = np.column_stack((np.ones_like(u), u, u * u))
    cov = np.linalg.inv(basis.T @ basis)
    return cov @ (basis.T @ values), cov


def _eval(coef, u):
    return coef[0] + np.multiply.outer(u, coef[1]) + np.multiply.outer(u * u, coef[2])


def _passes(coef, cov, u, pose, sigma):
    """Per frame (times ``u``, poses (k, 3)): within ``FLIGHT_SIGMAS`` of the fit's prediction,
    its own uncertainty included."""
    basis = np.column_stack((np.ones_like(u), u, u * u))
    q = np.einsum("ki,ij,kj->k", basis, cov, basis)
    return (np.abs(pose - _eval(coef, u)) <= FLIGHT_SIGMAS * sigma * np.sqrt(1.0 + q)[:, None]).all(axis=1)


def _seeds(tt, pose, sigma, dt):
    """Per frame: whether the ``SEED_FRAMES`` frames from it fit one quadratic within the noise
    (and have no time gap of an impact)."""
    count = tt.size - SEED_FRAMES + 1
    if count <= 0:
        return np.zeros(0, dtype=bool)
    rows = np.arange(count)[:, None] + np.arange(SEED_FRAMES)
    u = (tt[rows] - tt[rows[:, :1]]) / dt
    basis = np.stack((np.ones_like(u), u, u * u), axis=-1)
    coef = np.linalg.solve(np.einsum("pki,pkj->pij", basis, basis), np.einsum("pki,pkc->pic", basis, pose[rows]))
    resid = pose[rows] - np.einsum("pki,pic->pkc", basis, coef)
    ok = (np.abs(resid) <= FLIGHT_SIGMAS * sigma).all(axis=(1, 2))
    return ok & (np.diff(tt[rows], axis=1).max(axis=1) <= (IMPACT_GAP_FRAMES + 0.5) * dt)


def track_flights(t, x, y, phi, usable):
    """Free flights of one track found without g or the die: a list of :class:`_Flight`.

    A flight starts at the first ``SEED_FRAMES`` usable frames after the previous one that fit
    one quadratic in t per coordinate within ``FLIGHT_SIGMAS`` of the noise, and grows while the
    next frames stay within ``FLIGHT_SIGMAS`` of its prediction (a failing frame whose
    ``CONFIRM_FRAMES`` successors pass is a glitch and is skipped), in steps of half its length.
    """
    usable = np.asarray(usable, dtype=bool) & np.isfinite(t) & np.isfinite(x) & np.isfinite(y) & np.isfinite(phi)
    index = np.flatnonzero(usable)
    if index.size < MIN_FLIGHT_FRAMES:
        return []
    # third differences on any unit; phi keeps its own unit (R phi would mix the units that
    # are being checked)
    sigma = difference_noise(t, x, y, phi, usable, circumradius=1.0)
    if not np.isfinite(sigma).all():
        return []
    sigma = NOISE_EXCESS * sigma
    tt = t[index]
    pose = np.column_stack((x[index], y[index], phi[index]))
    dt = float(np.median(np.diff(tt)))
    gap = (IMPACT_GAP_FRAMES + 0.5) * dt
    seeds = _seeds(tt, pose, sigma, dt)
    flights = []
    start, count = 0, index.size
    while True:
        following = np.flatnonzero(seeds[start:])
        if following.size == 0:
            break
        start += int(following[0])
        rows = np.arange(start, start + SEED_FRAMES)
        t0 = tt[start]
        coef, cov = _fit((tt[rows] - t0) / dt, pose[rows])
        j = start + SEED_FRAMES
        while j < count and tt[j] - tt[rows[-1]] <= gap:
            cand = np.arange(j, min(j + max(2, rows.size // 2), count))
            cand = cand[: 1 + int(np.argmax(np.append(np.diff(tt[cand]) > gap, True)))]
            ok = _passes(coef, cov, (tt[cand] - t0) / dt, pose[cand], sigma)
            passed = int(np.argmin(np.append(ok, False)))
            if passed:
                rows = np.concatenate((rows, cand[:passed]))
                coef, cov = _fit((tt[rows] - t0) / dt, pose[rows])
                j = int(cand[passed - 1]) + 1
                continue
            # the frame fails: a glitch if the next frames fit the flight without it
            ahead = np.arange(j + 1, min(j + 1 + CONFIRM_FRAMES, count))
            if ahead.size == CONFIRM_FRAMES and tt[ahead[-1]] - tt[rows[-1]] <= gap + CONFIRM_FRAMES * dt \
                    and _passes(coef, cov, (tt[ahead] - t0) / dt, pose[ahead], sigma).all():
                j += 1
                continue
            break
        if rows.size >= MIN_FLIGHT_FRAMES:
            scale = np.array([1.0, 1.0 / dt, 1.0 / dt**2])  # back to s: c1 / dt, c2 / dt^2
            flights.append(_Flight(float(t0), float(tt[rows[0]]), float(tt[rows[-1]]), coef * scale[:, None],
                                   cov * np.outer(scale, scale), sigma, int(rows.size)))
            start = int(rows[-1]) + 1
        else:
            start += 1
    return flights


@dataclass(frozen=True)
class _Impact:
    time: float
    pose: np.ndarray  # (x, y, phi) where the two flights' positions cross
    dv: np.ndarray  # (dvx, dvy) after - before
    dv_sigma: float
    domega: float


def flight_impacts(flights):
    """Impacts between consecutive flights a few frames apart whose vertical velocity turns
    upwards significantly."""
    out = []
    for before, after in zip(flights, flights[1:]):
        gap = after.first - before.last
        dt = (before.last - before.first) / max(before.frames - 1, 1)
        if gap > (IMPACT_GAP_FRAMES + 0.5) * dt:
            continue
        times = np.linspace(before.last - dt, after.first + dt, 64)
        distance = np.linalg.norm(before.at(times)[:, :2] - after.at(times)[:, :2], axis=1)
        t_hit = float(times[np.argmin(distance)])
        v_before, v_after = before.velocity(t_hit), after.velocity(t_hit)
        dv = v_after[:2] - v_before[:2]
        dv_sigma = float(np.hypot(np.linalg.norm(before.velocity_sigma(t_hit)[:2]), np.linalg.norm(after.velocity_sigma(t_hit)[:2])))
        if not (v_before[1] < 0.0 and dv[1] > MIN_DV_SIGMAS * dv_sigma):
            continue
        pose = 0.5 * (before.at(t_hit) + after.at(t_hit))
        out.append(_Impact(t_hit, pose, dv, dv_sigma, float(v_after[2] - v_before[2])))
    return out


# --- evidence and judgement ------------------------------------------------------------------


@dataclass
class Evidence:
    """What the tracks say, per independent unit."""

    gravity: list = field(default_factory=list)  # per track: vertical acceleration (file units, > 0 down)
    kappa: list = field(default_factory=list)  # per impact: alpha R |dw| / |dv|
    contact: list = field(default_factory=list)  # per impact: lowest point's height, R
    rest_height: list = field(default_factory=list)  # per track at rest: centre height / apothem
    rest_angle: list = field(default_factory=list)  # per track at rest: |angle off the flat pose| / (pi / n)
    wrapped: list = field(default_factory=list)  # per track: True when its angle jumps by whole turns of 2 pi / n
    tracks: int = 0
    flights: int = 0


def _track_gravity(track, flights):
    """Inverse-variance mean of the vertical acceleration (down > 0, file units) of the flights
    that measure it (curvature ``MIN_CURVATURE_SIGMAS`` of its sigma, the die not resting:
    rocking and rest give short runs a curvature too) and rise or fall by ``MIN_FLIGHT_RISE``
    of the track's height range at least (not a die rocking on a corner); None if none does."""
    y = track.y[track.usable]
    span = float(np.ptp(y)) if y.size else 0.0
    acc, weight = [], []
    for f in flights:
        a, s = -f.acceleration[1], f.acceleration_sigma[1]
        times = np.linspace(f.first, f.last, 16)
        rise = float(np.ptp(f.at(times)[:, 1]))
        if abs(a) > MIN_CURVATURE_SIGMAS * s and rise >= MIN_FLIGHT_RISE * span:
            acc.append(a)
            weight.append(1.0 / s**2)
    if not acc:
        return None
    return float(np.dot(acc, weight) / np.sum(weight))


def _wraps(track, period):
    """Whether the track's angle jumps by a whole number of turns of 2 pi / n between two
    frames (beyond the motion of the frames around) and stays there; None for too few frames."""
    index = np.flatnonzero(track.usable)
    if index.size < 8:
        return None
    phi = track.phi[index]
    frames = np.diff(index).astype(float)
    rate = np.diff(phi) / frames
    padded = np.concatenate((np.full(3, np.nan), rate, np.full(3, np.nan)))
    local = np.nanmedian(np.lib.stride_tricks.sliding_window_view(padded, 7), axis=1)
    jump = np.diff(phi) - local * frames
    turns = np.round(jump / period)
    for k in np.flatnonzero((turns != 0) & (np.abs(jump - turns * period) < WRAP_TOLERANCE)):
        # it stays: the next frames sit a whole turn off the motion before the jump
        ahead = np.arange(k + 1, min(k + 5, phi.size))
        shift = phi[ahead] - phi[k] - local[k] * (index[ahead] - index[k])
        if ahead.size >= 2 and np.abs(shift - turns[k] * period).max() < 2.0 * WRAP_TOLERANCE:
            return True
    return False


def _tracking(cfg):
    """The declared measurement effects: (angle_offset, time_scale, length_scale, table_offset)."""
    tr = getattr(cfg, "tracking", None)

    def get(name, default):
        value = getattr(tr, name, default) if tr is not None else default
        return float(value) if value is not None else default

    return get("angle_offset", 0.0), get("time_scale", 1.0), get("length_scale", 1.0), get("table_offset", 0.0)


def measure(trackset, cfg):
    """:class:`Evidence` of a :class:`dice_sweep.measured.tracks.TrackSet` for the die of ``cfg``."""
    sides, radius = cfg.die.sides, cfg.die.circumradius
    angle_offset, _, length_scale, table_offset = _tracking(cfg)
    effects = getattr(cfg, "effects", None)
    alpha = float(inertia_ratio(sides)) * float(getattr(effects, "inertia", 1.0))  # I / M R^2, a declared inertia factor in
    corner_radius = float(getattr(effects, "corner_radius", 0.0))  # rounded corners: the lowest point is on an arc
    flat_height = float(apothem(sides, radius))
    period = 2.0 * math.pi / sides
    flat_phase = (DOWN - math.pi / sides) % period
    tracks = trackset.tracks
    if len(tracks) > MAX_TRACKS:
        tracks = [tracks[i] for i in np.linspace(0, len(tracks) - 1, MAX_TRACKS).round().astype(int)]
    ev = Evidence(tracks=len(tracks))

    def true_pose(y, phi):  # file -> the model's y (m) and phi (rad)
        return (np.asarray(y) - table_offset) / length_scale, np.asarray(phi) - angle_offset

    for track in tracks:
        usable = track.usable
        flights = track_flights(track.t, track.x, track.y, track.phi, usable)
        ev.flights += len(flights)
        g = _track_gravity(track, flights)
        if g is not None:
            ev.gravity.append(g)
        wrapped = _wraps(track, period)
        if wrapped is not None:
            ev.wrapped.append(wrapped)
        for hit in flight_impacts(flights):
            speed = float(np.linalg.norm(hit.dv))
            ev.kappa.append(alpha * radius * abs(hit.domega) / speed)
            y, phi = true_pose(hit.pose[1], hit.pose[2])
            ev.contact.append(float((y - support(sides, radius, phi, DOWN, corner_radius)) / radius))
        rest = rest_pose(track.x, track.y, track.phi, usable, radius, track.t)
        if rest is not None:
            y, phi = true_pose(rest[1], rest[2])
            ev.rest_height.append(float(y / flat_height))
            off = (phi - flat_phase + 0.5 * period) % period - 0.5 * period
            ev.rest_angle.append(float(abs(off) / (math.pi / sides)))
    return ev


@dataclass(frozen=True)
class Finding:
    """One check: ``status`` "ok", "warn", "error" or "skipped"; the measured value and its
    95 % interval; what was expected; one line saying it."""

    name: str
    status: str
    value: float
    interval: tuple
    expected: str
    message: str
    units: int = 0  # tracks or impacts it rests on

    def to_dict(self):
        return {"name": self.name, "status": self.status, "value": self.value, "ci95": list(self.interval),
                "expected": self.expected, "units": self.units, "message": self.message}


def _fmt(v):
    return f"{v:.3g}" if math.isfinite(v) else "nan"


def wilson_interval(hits, count, confidence=CONFIDENCE):
    """Share ``hits / count`` and its Wilson score interval: (share, low, high)."""
    if count == 0:
        return math.nan, math.nan, math.nan
    z = _z(confidence)
    p = hits / count
    centre = (p + z * z / (2 * count)) / (1 + z * z / count)
    half = z * math.sqrt(p * (1 - p) / count + z * z / (4 * count * count)) / (1 + z * z / count)
    return p, max(centre - half, 0.0), min(centre + half, 1.0)


def _status(low, high, error_band, warn_band):
    """"error" when the interval [low, high] lies wholly outside ``error_band`` (lo, hi),
    "warn" when wholly outside ``warn_band``, else "ok"."""
    if high < error_band[0] or low > error_band[1]:
        return "error"
    if high < warn_band[0] or low > warn_band[1]:
        return "warn"
    return "ok"


def _median_finding(name, what, values, unit, error_band, warn_band, expected, hint, minimum, kind="tracks"):
    value, lo, hi = median_interval(values)
    count = len(values)
    if count < minimum:
        return Finding(name, "skipped", value, (lo, hi), expected, f"{what}: {count} {kind}, too few to tell (need {minimum})", count)
    status = _status(lo, hi, error_band, warn_band)
    message = f"{what} {_fmt(value)}{unit} [95 % interval {_fmt(lo)}, {_fmt(hi)}] over {count} {kind} (expected {expected})"
    return Finding(name, status, value, (lo, hi), expected, message + (f"; {hint}" if status != "ok" else ""), count)


def _share_finding(name, what, hits, count, error, warn, expected, hint, minimum, kind):
    share, lo, hi = wilson_interval(hits, count)
    if count < minimum:
        return Finding(name, "skipped", share, (lo, hi), expected, f"{what}: {count} {kind}, too few to tell (need {minimum})", count)
    status = _status(lo, hi, (-math.inf, error), (-math.inf, warn))
    message = f"{what} {_fmt(share)} [95 % interval {_fmt(lo)}, {_fmt(hi)}] over {count} {kind} (expected {expected})"
    return Finding(name, status, share, (lo, hi), expected, message + (f"; {hint}" if status != "ok" else ""), count)


def judge(ev, cfg):
    """The findings of :class:`Evidence`, the most basic first: the units of length and time,
    the angle's unit and unwrapping, the dice at rest, then the impacts (the die and the
    angle's zero)."""
    sides, radius = cfg.die.sides, cfg.die.circumradius
    _, time_scale, length_scale, _ = _tracking(cfg)
    g_file = cfg.world.g * length_scale / time_scale**2
    die = f"the [die] ({sides} sides, R = {radius:.4g} m)"
    other_die = "another die ([die] sides, circumradius)"
    turn = f"{360 / sides:g} deg"
    findings = [
        _median_finding(
            "gravity", "free-flight vertical acceleration", ev.gravity, " m/s^2",
            (g_file / GRAVITY_ERROR, g_file * GRAVITY_ERROR), (g_file / GRAVITY_WARN, g_file * GRAVITY_WARN),
            f"{g_file:.4g} m/s^2, [world] g" + (" with the declared [tracking] scales" if g_file != cfg.world.g else ""),
            "x, y not in m, or t not in s (a wrong --rate or frame rate)?", MIN_TRACKS),
        _median_finding(
            "angle_unit", "spin change per velocity change at impacts, alpha R |d omega| / |dv|,", ev.kappa, "",
            (-math.inf, KAPPA_ERROR), (-math.inf, KAPPA_WARN),
            "at most 1 with phi in rad: the contact lies within R of the centre",
            "phi not in rad (degrees?), or the [die] circumradius far too large?", MIN_IMPACTS, "impacts"),
        _share_finding(
            "angle_wrap", f"share of tracks whose angle jumps by a whole {turn} turn between frames and stays", int(sum(ev.wrapped)),
            len(ev.wrapped), WRAP_ERROR, WRAP_WARN, f"below {WRAP_WARN}: phi unwrapped over turns",
            f"phi wrapped into a range of {turn}? unwrap it over turns", MIN_TRACKS, "tracks"),
        _median_finding(
            "rest_height", "centre height at rest over the apothem", ev.rest_height, "",
            (1.0 - REST_HEIGHT_ERROR, 1.0 + REST_HEIGHT_ERROR), (1.0 - REST_HEIGHT_WARN, 1.0 + REST_HEIGHT_WARN),
            f"1: a side flat on the table, the apothem {float(apothem(sides, radius)):.4g} m of {die}",
            f"{other_die}, or y not the height above the table?", MIN_TRACKS, "tracks at rest"),
        _median_finding(
            "rest_angle", "rest angle's distance from the flat pose, in units of pi/n,", ev.rest_angle, "",
            (-math.inf, REST_ANGLE_ERROR), (-math.inf, REST_ANGLE_WARN),
            f"0: corner 0 at the model's flat pose plus a multiple of {turn}",
            "phi's zero is not the model's angle (try --angle auto), or another die ([die] sides)?", MIN_TRACKS, "tracks at rest"),
        _median_finding(
            "contact_height", "height of the die's lowest point above y = 0 at impacts", ev.contact, " R",
            (-CONTACT_ERROR, CONTACT_ERROR), (-CONTACT_WARN, CONTACT_WARN),
            f"0 R: {die} at the model's angle touches the table at y = 0",
            f"y not the height above the table, {other_die}, or phi's zero not the model's?", MIN_IMPACTS, "impacts"),
        _share_finding(
            "contact_share", f"share of impacts whose lowest point is more than {CONTACT_OFF} R off the table",
            int(np.count_nonzero(np.abs(ev.contact) > CONTACT_OFF)), len(ev.contact), CONTACT_SHARE_ERROR, CONTACT_SHARE_WARN,
            f"below {CONTACT_SHARE_WARN}: {die} at the model's angle touches the table with a corner or a side",
            f"{other_die}, phi's zero not the model's (try --angle auto), or y not the height above the table?", MIN_IMPACTS, "impacts"),
    ]
    # a quantity no check could decide rests on weak evidence: one line says which (none when
    # no flight was found at all: the command's own error says that the tracks are unusable)
    decided = {f.name for f in findings if f.status != "skipped"}
    unchecked = [label for label, names in (("the units of length and time", ("gravity",)), ("the angle's unit", ("angle_unit",)),
                                            ("the die and the angle's zero", ("contact_share", "rest_angle"))) if not decided & set(names)]
    if unchecked and ev.flights:
        findings.append(Finding(
            "evidence", "warn", math.nan, (math.nan, math.nan), "",
            f"{', '.join(unchecked)} not checked: too little evidence ({ev.flights} flights, {len(ev.contact)} impacts and "
            f"{len(ev.rest_height)} tracks at rest found in {ev.tracks} tracks; need {MIN_TRACKS} tracks with a flight, "
            f"{MIN_IMPACTS} impacts or {MIN_TRACKS} tracks at rest)", 0))
    return findings


def check_measured(trackset, cfg):
    """Run the checks on tracks just read (unless :func:`settings` turned them off): raise
    one line for the first error, warn for each warning.

    Raises
    ------
    DiceSweepError
        ``FILE: checks: QUANTITY VALUE [LOW, HIGH] ... (expected ...); hint (skip: --no-check-units)``.
    """
    enabled, warn = _SETTINGS.get()
    if not enabled:
        return []
    warn = warn or _default_warn
    findings = judge(measure(trackset, cfg), cfg)
    errors = [f for f in findings if f.status == "error"]
    if errors:
        more = f" ({len(errors) - 1} more check{'s' if len(errors) > 2 else ''} failed: {', '.join(f.name for f in errors[1:])})" if len(errors) > 1 else ""
        raise DiceSweepError(f"{trackset.path}: check {errors[0].name}: {errors[0].message}{more} (skip the checks: --no-check-units)")
    for f in findings:
        if f.status == "warn":
            warn(f"{trackset.path}: check {f.name}: {f.message}")
    return findings
