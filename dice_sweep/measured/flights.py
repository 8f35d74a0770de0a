"""Free flights of a tracked die, and the tracking noise measured on them.

A *free flight* is a run of usable frames in which the die touches nothing: x and phi linear in
t, y a parabola of curvature -g, all to within the tracking noise (each coordinate's curvature
may be off by ``CURVATURE_TOLERANCE`` g: air drag, the camera's length scale). Flights are
separated by impacts: the lowest corner (:func:`dice_sweep.measured.impacts.lowest_height`)
reaches the table and the velocity changes.

:func:`find_flights` segments one track without any threshold in m/s: every decision is a test
scaled by the noise (given, or the track's own, :func:`segment_track`) or by the geometry.

1. *Seeds*: runs of ``MIN_FLIGHT_FRAMES`` usable frames whose ballistic fit passes a chi-square
   test, with the lowest corner clear of the table by its fit and in every frame: above the
   *contact band*, ``CONTACT_SIGMAS`` sigma of the lowest corner's measured height.
2. *Growth*: from the first seed after the previous flight, each next frame is predicted from
   the fit so far (a chi-square test with 3 degrees of freedom, the fit's own uncertainty
   included). A failing frame is a tracking glitch, and is skipped, if the ``CONFIRM_FRAMES``
   frames after it pass; otherwise the flight ends before it. It ends too where the predicted
   lowest corner enters the contact band (here ``CONTACT_SIGMAS`` sigma of the prediction):
   that is where the impact is.
3. *Backwards*: the flight's fit is walked back from the seed the same way, so both ends are
   placed from the inside. End frames are judged by the rest of the flight (leave-one-out), and
   frames whose own measured lowest corner is in the band are contact frames, in no flight.
   Frames that two neighbouring flights both explain lie around their impact: neither keeps them.
4. *Merges*: two neighbouring flights that one flight explains as well (a likelihood-ratio test,
   6 parameters) were split by noise, and are joined.
5. The track ends at *sustained contact*: ``CONTACT_TIME`` with the lowest corner in the
   contact band (``CONTACT_SHARE`` of its frames), or a die that does not move.

:func:`estimate_noise` fits every flight of many tracks and pools the residuals, corrected for
the fitted parameters, with a bootstrap over tracks for the intervals.
"""

import math
from dataclasses import dataclass

import numpy as np

from dice_sweep.geometry import DOWN
from dice_sweep.measured.impacts import lowest_height

__all__ = [
    "Segmentation",
    "NoiseEstimate",
    "MIN_FLIGHT_FRAMES",
    "find_flights",
    "segment_track",
    "difference_noise",
    "estimate_noise",
]

MIN_FLIGHT_FRAMES = 4  # usable frames: fewer leave no check on a 2-parameter fit per coordinate
# Air drag (c |v| v ~ 0.2 m/s^2 at 2 m/s) and a length scale off by a few per cent (the shared
# data's flights curve at about 9.4 m/s^2) bend a flight away from -g: a Gaussian prior of this
# width (in g) on each coordinate's curvature lets a fit absorb them.
CURVATURE_TOLERANCE = 0.1
# Probability that a frame of a free flight fails a chi-square test by noise alone: one flight
# of 30 frames in 30 sees a false alarm, which ends it only if the next frames fail too (and
# the merge test joins the pieces again).
FALSE_ALARM = 1e-3
CONFIRM_FRAMES = 2  # frames after a failing one that must pass for it to be a glitch ...
MAX_OUTLIER_RUN = 2  # ... of at most this many frames (longer runs end the flight)
# The contact band: the lowest corner lower than this many sigma of its height (or
# CONTACT_FLOOR R, for rounded corners and the table level's own error) may touch the table.
CONTACT_SIGMAS = 2.0
CONTACT_FLOOR = 0.01  # R
CONTACT_TIME = 0.04  # s: a flight this long rises g t^2 / 8 = 2 mm; a contact this long is sustained
CONTACT_SHARE = 0.8  # of CONTACT_TIME's frames in the contact band: sustained (a flat landing may
# sit 20 ms on the table, then hop; noise lifts a frame at rest out of the band now and then)
# A die whose pose scatters by less than this many sigma (rms) over CONTACT_TIME is still, if a
# flight that long would move y by more than 1 / STILL_SHARE times that (else the test is off)
STILL_SIGMAS = 2.0
STILL_SHARE = 0.5
NOISE_FLOOR = 1e-6  # m: the shared data's rounding; no noise estimate goes below it
MAD_TO_SIGMA = 1.4826  # standard deviation of Gaussian noise per median absolute deviation
THIRD_DIFFERENCE_GAIN = math.sqrt(20.0)  # sd of a third difference of white noise, per sigma
EQUAL_STEPS = 0.01  # relative: a third difference needs three steps equal to within this
MIN_DIFFERENCES = 8  # third differences: fewer give no noise estimate
# Without a given noise, ballistic fits over windows this long (frames) measure the scatter that
# a flight's fit sees: the shared data's tracking errors last a few frames, and differences miss
# part of them (8 frames: 5 degrees of freedom each, and most windows clear of impacts)
NOISE_WINDOW = 8
# ... and the median of their scatter is taken (windows over impacts are a minority), but at
# most WINDOW_EXCESS times the differences' noise: the shared data's windows scatter 1.3 to 1.5
# times as much, and more is windows over impacts and glitches in a short track
WINDOW_EXCESS = 2.0
TIME_UNIT_FRAMES = 16.0  # the fits' time unit in frames: keeps their normal equations well scaled
CHUNK_FRAMES = 32  # windows tested at once while a flight grows (most flights end in the first)
# The noise fits are a quadratic in t for each of x, y and R phi: the curvature is free as the
# segmentation's prior lets it be (drag; on the shared data x and phi slow down after the first
# impact, 0.7 m/s^2 and 17 rad/s^2, the plate rubbing its guides?). This costs a degree of
# freedom per flight and coordinate, and no bias.
FIT_PARAMETERS = 3
NOISE_CLEARANCE = 2.0  # sigma of the lowest corner's height: frames nearer the contact band are
# left out of the noise fits (the contact tests chose them by their own noise)
BOOTSTRAP_SAMPLES = 2000
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Segmentation:
    """The free flights of one track, and what decided them.

    Attributes
    ----------
    flights : list of (int, int)
        Inclusive (first, last) frame indices of each flight, in time order.
    outliers : numpy.ndarray of bool
        Per frame: usable frames inside a flight that its fit left out (tracking glitches not
        flagged by the tracker).
    noise : numpy.ndarray, shape (3,)
        Noise sigma of x, y (m) and phi (rad) used.
    band : float
        Contact band, m above the table: a fitted lowest corner lower than this may touch it.
    contact : int or None
        First frame of the sustained contact that ends the track (None: none found).

    A track without a noise estimate (fewer than ``MIN_DIFFERENCES`` + 3 usable frames and no
    ``noise`` given) has no flights.
    """

    flights: list
    outliers: np.ndarray
    noise: np.ndarray
    band: float
    contact: object

    def flight_frames(self, usable):
        """Frames each flight's fit uses: ``usable`` in the flight and not an outlier.

        Returns
        -------
        list of numpy.ndarray of int
        """
        keep = np.asarray(usable, dtype=bool) & ~self.outliers
        return [first + np.flatnonzero(keep[first : last + 1]) for first, last in self.flights]


@dataclass(frozen=True)
class NoiseEstimate:
    """Tracking noise from the residuals of ballistic fits over free flights.

    Attributes
    ----------
    sigma : numpy.ndarray, shape (3,)
        Noise sigma of x (m), y (m) and phi (rad).
    interval : numpy.ndarray, shape (3, 2)
        95 % bootstrap interval (over tracks) of each sigma.
    pose : float
        Combined pose noise sqrt(sx^2 + sy^2 + (R sphi)^2), m.
    pose_interval : tuple of float
        Its 95 % bootstrap interval, m.
    tracks, flights, frames : int
        Tracks with at least one flight, flights and frames fitted.
    dof : numpy.ndarray, shape (3,)
        Residual degrees of freedom of x, y, phi (frames less ``FIT_PARAMETERS`` per flight).
    """

    sigma: np.ndarray
    interval: np.ndarray
    pose: float
    pose_interval: tuple
    tracks: int
    flights: int
    frames: int
    dof: np.ndarray


# --- statistics ----------------------------------------------------------------------------


def _normal_quantile(p):
    """Upper quantile z of the standard normal, P(Z > z) = p < 0.02425 (Acklam's rational
    approximation of the lower tail, relative error 1e-9)."""
    q = math.sqrt(-2.0 * math.log(p))
    num = 0.0
    for c in (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838, -2.549732539343734, 4.374664141464968, 2.938163982698783):
        num = num * q + c
    den = 0.0
    for d in (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996, 3.754408661907416, 1.0):
        den = den * q + d
    return -num / den


def _chi2_quantile(dof, p):
    """Upper quantile of chi-square with ``dof`` degrees of freedom (Wilson-Hilferty; at 3
    degrees of freedom and p = 1e-3 it gives 16.55 for the exact 16.27)."""
    z = _normal_quantile(p)
    k = 2.0 / (9.0 * dof)
    return dof * (1.0 - k + z * math.sqrt(k)) ** 3


# --- noise ---------------------------------------------------------------------------------


def _pose_rows(t, x, y, phi, circumradius, g):
    """(tau, Y) of frames: tau the time from the first (s), Y = (x, y + g tau^2 / 2, R phi) (m),
    which is linear in tau in free flight."""
    tau = t - t[0]
    return tau, np.column_stack((x, y + 0.5 * g * tau * tau, circumradius * phi))


def difference_noise(t, x, y, phi, usable, *, circumradius):
    """Noise sigma of x, y (m) and phi (rad) from a track's third differences.

    The third difference of four consecutive frames is noise alone wherever the acceleration
    is constant: in free fall, at rest and in slow rocking alike (a second difference of y
    would carry g dt^2 at rest, 0.16 mm at 250 Hz). Only impacts disturb it, so its median
    absolute deviation, scaled to a Gaussian's sigma and divided by sqrt(20), is the noise.
    Only runs of three equal time steps count.

    Parameters
    ----------
    t, x, y, phi : numpy.ndarray
        One track (s, m, m, rad).
    usable : numpy.ndarray of bool
        Frames to use.
    circumradius : float
        R, m (phi's noise is found as R phi's).

    Returns
    -------
    numpy.ndarray, shape (3,)
        Sigma of x, y (m) and phi (rad), at least ``NOISE_FLOOR``; NaN where fewer than
        ``MIN_DIFFERENCES`` third differences exist.
    """
    index = np.flatnonzero(np.asarray(usable, dtype=bool) & np.isfinite(t) & np.isfinite(x) & np.isfinite(y) & np.isfinite(phi))
    if index.size < MIN_DIFFERENCES + 3:
        return np.full(3, np.nan)
    pose = np.column_stack((x[index], y[index], circumradius * phi[index]))
    steps = np.diff(t[index])
    equal = (np.abs(steps[1:-1] - steps[:-2]) <= EQUAL_STEPS * steps[:-2]) & (np.abs(steps[2:] - steps[:-2]) <= EQUAL_STEPS * steps[:-2])
    if np.count_nonzero(equal) < MIN_DIFFERENCES:
        return np.full(3, np.nan)
    third = (pose[3:] - 3.0 * pose[2:-1] + 3.0 * pose[1:-2] - pose[:-3])[equal]
    spread = MAD_TO_SIGMA * np.median(np.abs(third - np.median(third, axis=0)), axis=0) / THIRD_DIFFERENCE_GAIN
    sigma = np.maximum(spread, NOISE_FLOOR)
    sigma[2] /= circumradius
    return sigma


# --- fits ----------------------------------------------------------------------------------


class _Fits:
    """Ballistic fits of all three pose coordinates, one per window (or one for many rows).

    Each coordinate is ``b0 + b1 u + b2 u^2 / 2`` (u the time in fit units) with a Gaussian
    prior on b2; the three normal matrices share the basis sums and differ only in the prior,
    so their inverses come from one set of cofactors (closed form, vectorised).

    Parameters
    ----------
    sums : numpy.ndarray, shape (E, 3, 3)
        Basis sums of each window.
    rhs : numpy.ndarray, shape (E, 3, 3)
        Sums of basis function i times coordinate c, [window, i, c].
    prior : numpy.ndarray, shape (3,)
        Prior precision of each coordinate's b2, in units of its noise variance.
    """

    def __init__(self, sums, rhs, prior):
        s00, s01, s02 = sums[:, 0, 0, None], sums[:, 0, 1, None], sums[:, 0, 2, None]
        s11, s12, s22 = sums[:, 1, 1, None], sums[:, 1, 2, None], sums[:, 2, 2, None]
        f = s22 + prior  # (E, 3): the only entry that differs between coordinates
        c00 = s11 * f - s12 * s12
        c01 = s02 * s12 - s01 * f
        c11 = s00 * f - s02 * s02
        c02 = s01 * s12 - s11 * s02  # these three do not depend on the prior: (E, 1)
        c12 = s01 * s02 - s00 * s12
        c22 = s00 * s11 - s01 * s01
        scale = 1.0 / (s00 * c00 + s01 * c01 + s02 * c02)
        i00, i01, i02, i11, i12, i22 = c00 * scale, c01 * scale, c02 * scale, c11 * scale, c12 * scale, c22 * scale
        self.cof = (i00, 2.0 * i01, 2.0 * i02, i11, 2.0 * i12, i22)  # for q = x' A^-1 x
        r0, r1, r2 = rhs[:, 0], rhs[:, 1], rhs[:, 2]
        self.b0 = i00 * r0 + i01 * r1 + i02 * r2
        self.b1 = i01 * r0 + i11 * r1 + i12 * r2
        self.b2 = i02 * r0 + i12 * r1 + i22 * r2

    def pick(self, k):
        """The fit of window ``k`` alone."""
        one = object.__new__(_Fits)
        one.cof = tuple(c[k : k + 1] for c in self.cof)
        one.b0, one.b1, one.b2 = self.b0[k : k + 1], self.b1[k : k + 1], self.b2[k : k + 1]
        return one

    def at(self, u):
        """Fitted coordinates (..., 3) at times ``u`` (shape (E, 1), or (rows, 1) for one
        fit), and q = x' A^-1 x, the fit's variance there per unit noise variance."""
        half = 0.5 * u * u
        i00, i01x2, i02x2, i11, i12x2, i22 = self.cof
        q = i00 + u * (i01x2 + u * i11) + half * (i02x2 + u * i12x2 + half * i22)
        return self.b0 + u * self.b1 + half * self.b2, q


class _Track:
    """One track's usable frames, prepared for the fits (all pose coordinates in m)."""

    def __init__(self, t, x, y, phi, usable, sides, circumradius, g, noise, table):
        usable = np.asarray(usable, dtype=bool) & np.isfinite(t) & np.isfinite(x) & np.isfinite(y) & np.isfinite(phi)
        self.index = np.flatnonzero(usable)
        self.sides, self.radius, self.g, self.table = sides, circumradius, g, table
        self.spacing = 2.0 * math.pi / sides  # between corners, rad
        self.count = self.index.size
        if self.count < 2:
            self.tau, self.pose, self.dt = np.zeros(self.count), np.zeros((self.count, 3)), 1.0
        else:
            self.tau, self.pose = _pose_rows(t[self.index], x[self.index], y[self.index], phi[self.index], circumradius, g)
            self.dt = float(np.median(np.diff(self.tau)))
        self.fall = 0.5 * g * self.tau * self.tau  # to turn Y back into y
        self.unit = TIME_UNIT_FRAMES * self.dt  # s, the fits' time unit
        self.frame_test = _chi2_quantile(3, FALSE_ALARM)
        self.split_test = _chi2_quantile(6, FALSE_ALARM)  # one flight against two: 6 more parameters
        self.floor = CONTACT_FLOOR * circumradius
        self.height = lowest_height(sides, circumradius, self.pose[:, 1] - self.fall, self.pose[:, 2] / circumradius, table)
        self.set_noise(noise)

    def set_noise(self, noise):
        """Use the noise sigma (x, y in m, phi in rad) for every test."""
        self.noise = np.array(noise, dtype=float)
        sig = np.array([self.noise[0], self.noise[1], self.radius * self.noise[2]])
        sig = np.where(np.isfinite(sig), np.maximum(sig, NOISE_FLOOR), np.inf)
        self.var = sig * sig
        # prior precision of the curvature coefficient (basis u^2 / 2, u in fit time units)
        self.prior = self.var / (CURVATURE_TOLERANCE * self.g * self.unit**2) ** 2
        # for a frame alone (seeds, sustained contact): the measured height's own noise
        self.band = max(CONTACT_SIGMAS * math.sqrt(sig[1] ** 2 + sig[2] ** 2), self.floor)

    def lowest(self, pose, rows):
        """Height of the lowest corner above the table (m) of Y-like poses (..., 3) at ``rows``
        (:func:`dice_sweep.measured.impacts.lowest_height`, written out for speed)."""
        offset = np.mod(DOWN - pose[..., 2] / self.radius, self.spacing)
        reach = self.radius * np.cos(np.minimum(offset, self.spacing - offset))
        return pose[..., 1] - self.fall[rows] - reach - self.table

    def fit(self, rows, origin, weight=None):
        """One ballistic fit of ``rows`` (weights 0 or 1), time from row ``origin``: (_Fits, u)."""
        u = (self.tau[rows] - self.tau[origin]) / self.unit
        basis = _basis(u)
        wb = basis if weight is None else basis * weight[:, None]
        return _Fits((wb.T @ basis)[None], (wb.T @ self.pose[rows])[None], self.prior), u[:, None]

    def chi2(self, rows, origin):
        """Penalised chi-square of the fit of ``rows`` (curvature prior included)."""
        fits, u = self.fit(rows, origin)
        pred, _ = fits.at(u)
        return float(np.sum(((self.pose[rows] - pred) ** 2).sum(axis=0) / self.var + self.prior * fits.b2[0] ** 2 / self.var))

    def test(self, fits, u, rows, fitted=False):
        """Rows against fits: chi-square (3 degrees of freedom) of each row's residual, the
        lowest corner's height predicted there (m) and the contact band there (m).

        ``fits`` holds one fit per row (u of shape (E, 1)) or one for all. ``fitted`` (bool, or
        bool per row): the row is in the fit, and is judged by the others: the fit without it
        (leave-one-out: residual / (1 - q), variance factor q / (1 - q)), not by itself.
        """
        pred, q = fits.at(u)
        ys = self.pose[rows]
        if fitted is not False:
            keep = np.maximum(1.0 - q, 1e-9)
            if fitted is True:
                pred, q = ys - (ys - pred) / keep, q / keep
            else:
                inside = fitted[:, None]
                pred = np.where(inside, ys - (ys - pred) / keep, pred)
                q = np.where(inside, q / keep, q)
        residual = ys - pred
        z2 = (residual * residual / (self.var * (1.0 + q))).sum(axis=1)
        # the lowest corner moves with y, and at most as fast as R phi
        band = np.maximum(CONTACT_SIGMAS * np.sqrt(self.var[1] * q[:, 1] + self.var[2] * q[:, 2]), self.floor)
        return z2, self.lowest(pred, rows), band


def _basis(u):
    """(..., 3) basis 1, u, u^2 / 2 of a flight."""
    basis = np.empty(u.shape + (3,))
    basis[..., 0] = 1.0
    basis[..., 1] = u
    basis[..., 2] = 0.5 * u * u
    return basis


def _seeds(track, size):
    """Which runs of ``size`` rows starting at each row are seeds (bool per row): ballistic
    to within the noise (chi-square), and clear of the table by their fit and by every frame."""
    count = track.count - size + 1
    out = np.zeros(track.count, dtype=bool)
    if count <= 0:
        return out
    rows = np.arange(count)[:, None] + np.arange(size)
    u = (track.tau[rows] - track.tau[rows[:, :1]]) / track.unit  # (P, m)
    basis = _basis(u)  # (P, m, 3)
    ys = track.pose[rows]  # (P, m, 3 coordinates)
    fits = _Fits(np.einsum("pki,pkj->pij", basis, basis), np.einsum("pki,pkc->pic", basis, ys), track.prior)
    half = 0.5 * u * u
    fitted = fits.b0[:, None] + u[..., None] * fits.b1[:, None] + half[..., None] * fits.b2[:, None]
    chi2 = np.sum(((ys - fitted) ** 2).sum(axis=1) / track.var + track.prior * fits.b2**2 / track.var, axis=1)
    clear = ((track.lowest(fitted, rows) >= track.band) & (track.height[rows] >= track.band)).all(axis=1)
    out[:count] = (chi2 <= _chi2_quantile(3 * size - 6, FALSE_ALARM)) & clear
    return out


def _glitch_run(passes, known, at):
    """Rows to skip as a glitch when row ``at`` of a walk fails: itself and up to
    ``MAX_OUTLIER_RUN`` - 1 more, if the next ``CONFIRM_FRAMES`` rows not ``known`` to be
    outliers pass; None if they do not (the flight ends there)."""
    ahead = at + 1 + np.flatnonzero(~known[at + 1 :])[: MAX_OUTLIER_RUN - 1 + CONFIRM_FRAMES]
    for run in range(MAX_OUTLIER_RUN):
        if run + CONFIRM_FRAMES <= ahead.size and passes[ahead[run : run + CONFIRM_FRAMES]].all():
            return np.concatenate(([at], ahead[:run]))
    return None


def _grow(track, start, stop, size, outliers):
    """Grow a flight forward from the seed of ``size`` rows at ``start`` (up to ``stop``,
    exclusive).

    Each next row is predicted from the fit of the rows so far and tested: chi-square against
    the noise and the fit's own uncertainty, and the predicted lowest corner against the contact
    band. A failing row is a glitch (set in ``outliers``, in place) when the rows after it fit;
    rows already set there do not count.

    Returns
    -------
    end : int
        Last row, after the rows whose fitted lowest corner is in the contact band are trimmed
        off (``start - 1`` when nothing is left).
    fit : _Fits or None
        The flight's fit, time from row ``start``.
    landed : bool
        Whether the flight ended with its lowest corner in the contact band.
    """
    rows = np.arange(start, stop)
    n = rows.size
    if n < size:
        return start - 1, None, False
    u = (track.tau[rows] - track.tau[start]) / track.unit
    basis = _basis(u)
    ys = track.pose[rows]
    known = outliers[rows].copy()
    weight = (~known).astype(float)
    counted = np.cumsum(weight)
    if counted[-1] < size:
        return start - 1, None, False
    first = int(np.argmax(counted >= size))  # first window end tested: a seed's worth of rows
    seed_end = first
    end = n - 1
    stale, last_fit, landed = True, None, False
    while first < n - 1:
        if stale:  # window sums, after the weights changed
            wb = basis * weight[:, None]
            sums = np.cumsum(wb[:, :, None] * basis[:, None, :], axis=0)
            rhs = np.cumsum(wb[:, :, None] * ys[:, None, :], axis=0)  # (n, 3 basis, 3 coordinates)
            stale = False
        ends = np.arange(first, min(first + CHUNK_FRAMES, n - 1))
        nxt = ends + 1
        fits = _Fits(sums[ends], rhs[ends], track.prior)
        z2, low, band = track.test(fits, u[nxt, None], rows[nxt])
        hits = np.flatnonzero(((z2 > track.frame_test) | (low < band)) & ~known[nxt])
        if hits.size == 0:
            first = int(ends[-1]) + 1
            continue
        k = int(hits[0])
        j = int(nxt[k])  # the failing row (slice position)
        end = j - 1
        last_fit = fits.pick(k)  # the fit of the rows up to ``end``
        if low[k] < band[k]:
            landed = True
            break
        # a glitch, if the rows after it fit the flight so far
        later = np.arange(j + 1, min(j + 1 + MAX_OUTLIER_RUN + CONFIRM_FRAMES, n))
        za, la, ba = track.test(last_fit, u[later, None], rows[later])
        passes = np.zeros(n, dtype=bool)
        passes[later] = (za <= track.frame_test) & (la >= ba)
        skip = _glitch_run(passes, known, j)
        if skip is None:
            break
        known[skip] = True
        weight[skip] = 0.0
        outliers[rows[skip]] = True
        first, end, stale, last_fit = j - 1, n - 1, True, None
    # trim: the last rows may already be in the contact band by the flight's own fit
    if end == n - 1:  # grown to the end: no window fit holds the last row yet
        last_fit = None
    while end >= seed_end and known[end]:
        end -= 1
    if end < seed_end:
        return start - 1, None, False
    keep = slice(0, end + 1)
    fit = last_fit
    if fit is None:
        wb = basis[keep] * weight[keep, None]
        fit = _Fits((wb.T @ basis[keep])[None], (wb.T @ ys[keep])[None], track.prior)
    _, low, band = track.test(fit, u[keep, None], rows[keep], fitted=True)
    clear = np.flatnonzero((low >= band) & ~known[keep])
    if clear.size == 0:
        return start - 1, None, False
    outliers[rows[clear[-1] + 1 : end + 1]] = False
    return int(rows[clear[-1]]), fit, landed or clear[-1] < end


def _extend_back(track, fit, start, size, floor, outliers):
    """First row of a flight grown forward from the seed at ``start`` (``fit``, time from
    ``start``), walked backwards from the seed's last row to ``floor`` (exclusive) with the
    growth's tests: the seed's rows judged by the rest of the flight (leave-one-out), the rows
    before it predicted. A failing row is a glitch (set in ``outliers``) when the rows before it
    pass; else, or in the contact band, the flight starts after it (a seed that straddled an
    impact loses its early rows so)."""
    rows = np.arange(start + size - 1, floor, -1)
    z2, low, band = track.test(fit, (track.tau[rows, None] - track.tau[start]) / track.unit, rows, fitted=rows >= start)
    passes = (z2 <= track.frame_test) & (low >= band)
    known = outliers[rows]
    begin = start + size - 1
    at = 0
    while at < rows.size:
        if known[at] or passes[at]:
            begin = rows[at] if not known[at] else begin
            at += 1
            continue
        if low[at] < band[at]:
            break
        skip = _glitch_run(passes, known, at)
        if skip is None:
            break
        known[skip] = True
        outliers[rows[skip]] = True
        at += 1
    return int(begin)


def _merge(track, found, outliers):
    """Join neighbouring flights that one flight explains as well: a likelihood-ratio test of
    the split (6 more parameters), the frames between them predicted by the joint fit and its
    lowest corner clear of the table. Splits by noise alone are rare, and go."""
    merged = [found[0][:2]]
    for (begin, end), (_, _, landed) in zip((flight[:2] for flight in found[1:]), found[:-1]):
        first, last = merged[-1]
        if landed:  # the first flight's own fit reached the table: an impact
            merged.append((begin, end))
            continue
        rows = np.arange(first, end + 1)
        rows = rows[~outliers[rows]]
        inside = (rows <= last) | (rows >= begin)
        between = rows[~inside]
        joined = False
        if np.all(track.height[between] >= track.band):  # else a frame between is at the table
            joint, u = track.fit(rows[inside], first)
            _, low, band = track.test(joint, u, rows[inside], fitted=True)
            zb, lb, bb = track.test(joint, (track.tau[between, None] - track.tau[first]) / track.unit, between)
            # the frames between may hold glitches, as a flight may
            fits_between = np.count_nonzero(zb > track.frame_test) <= MAX_OUTLIER_RUN
            if (low >= band).all() and fits_between and (lb >= bb).all():
                split = track.chi2(rows[inside], first) - track.chi2(rows[rows <= last], first) - track.chi2(rows[rows >= begin], begin)
                joined = split <= track.split_test
        if joined:
            merged[-1] = (first, end)
            outliers[between[zb > track.frame_test]] = True
        else:
            merged.append((begin, end))
    return merged


def _sustained_contact(track, window):
    """First row of sustained contact: the first row at the table of ``window`` rows with the
    lowest corner in the contact band in ``CONTACT_SHARE`` of them, or the first of ``window``
    rows in which the die stays still (count if none)."""
    if track.count < window:
        return track.count
    low = track.height < track.band
    inside = np.concatenate(([0], np.cumsum(low)))
    starts = np.flatnonzero(inside[window:] - inside[:-window] >= CONTACT_SHARE * window)
    stop = int(starts[0] + np.argmax(low[starts[0] :])) if starts.size else track.count
    # still: each coordinate's spread over the window within STILL_SIGMAS sigma, when a flight
    # that long (rising and falling g t^2 / 8) could not be that still
    if STILL_SIGMAS**2 * track.var[1] < (STILL_SHARE * track.g * (window * track.dt) ** 2 / 8.0) ** 2:
        pose = track.pose[:stop] - track.pose[0]
        pose[:, 1] -= track.fall[:stop]
        sums = np.concatenate((np.zeros((1, 3)), np.cumsum(pose, axis=0)))
        squares = np.concatenate((np.zeros((1, 3)), np.cumsum(pose * pose, axis=0)))
        mean = (sums[window:] - sums[:-window]) / window
        spread = (squares[window:] - squares[:-window]) / window - mean * mean
        still = np.flatnonzero((spread <= STILL_SIGMAS**2 * track.var).all(axis=1))
        if still.size:
            stop = int(still[0])
    return stop


def _segment(track):
    """Flights (first row, last row), outlier rows and the row where sustained contact starts."""
    size = MIN_FLIGHT_FRAMES
    outliers = np.zeros(track.count, dtype=bool)
    if track.count < size or not np.isfinite(track.var).all():
        return [], outliers, track.count
    seeds = _seeds(track, size)
    stop = _sustained_contact(track, max(size, int(round(CONTACT_TIME / track.dt))))
    found = []
    lower = 0
    while True:
        candidates = np.flatnonzero(seeds[lower : max(stop - size + 1, lower)])
        if candidates.size == 0:
            break
        seed = lower + int(candidates[0])
        floor = found[-1][0] + size - 1 if found else -1  # may reach into the previous flight
        skipped = outliers.copy()  # glitches this attempt skips
        end, fit, landed = _grow(track, seed, stop, size, skipped)
        begin = _extend_back(track, fit, seed, size, floor, skipped) if fit is not None else seed
        # frames at the table by their own measured height are contact frames, at either end
        while begin < end and track.height[begin] < track.band:
            begin += 1
        while end > begin and track.height[end] < track.band:
            end -= 1
        if end - begin + 1 < size:
            lower = max(seed, end) + 1
            continue
        if found and begin <= found[-1][1]:
            # rows both flights explain lie around the impact: neither gets them
            previous = found.pop()
            if begin - previous[0] >= size:
                found.append((previous[0], begin - 1) + previous[2:])
            begin = previous[1] + 1
        if end - begin + 1 - np.count_nonzero(skipped[begin : end + 1]) >= size:
            found.append((begin, end, landed))
            outliers[begin : end + 1] = skipped[begin : end + 1]
        lower = end + 1
    if len(found) > 1:
        return _merge(track, found, outliers), outliers, stop
    return [flight[:2] for flight in found], outliers, stop


def _quadratic_design(tau):
    """(rows, FIT_PARAMETERS) design of the noise fits: powers of the time scaled to [0, 1]."""
    u = tau - tau[0]
    u = u / max(u[-1], 1e-12)
    return u[:, None] ** np.arange(FIT_PARAMETERS)


def _clear_rows(t, pose, groups, seg, sides, circumradius, table):
    """Each group's rows whose lowest corner, on the group's quadratic fit, clears the contact
    band by ``NOISE_CLEARANCE`` sigma of its height: nearer the table, the contact tests kept or
    dropped a frame by its own noise, which would bias the noise low."""
    margin = seg.band + NOISE_CLEARANCE * math.hypot(seg.noise[1], circumradius * seg.noise[2])
    kept = []
    for rows in groups:
        design = _quadratic_design(t[rows])
        fitted = design @ np.linalg.lstsq(design, pose[rows], rcond=None)[0]
        height = lowest_height(sides, circumradius, fitted[:, 1], fitted[:, 2] / circumradius, table)
        rows = rows[height >= margin]
        if rows.size >= MIN_FLIGHT_FRAMES:
            kept.append(rows)
    return kept


def _residual_sums(tau, pose, groups):
    """Residual sums of squares (3,) of the pose coordinates (x, y, R phi; m^2) over groups of
    rows, each fitted on its own (a quadratic in tau), and their degrees of freedom (3,)."""
    rss, dof = np.zeros(3), np.zeros(3)
    for rows in groups:
        if rows.size <= FIT_PARAMETERS:
            continue
        design = _quadratic_design(tau[rows])
        residual = pose[rows] - design @ np.linalg.lstsq(design, pose[rows], rcond=None)[0]
        rss += (residual * residual).sum(axis=0)
        dof += rows.size - FIT_PARAMETERS
    return rss, dof


def _window_noise(track, rows):
    """Noise sigma (x, y, R phi; m) from ballistic fits (quadratics) over windows of
    ``NOISE_WINDOW`` rows among the first ``rows``: the median of their residual sums of
    squares, which windows over impacts or glitches (a minority) do not move, over the median
    of chi-square. NaN when there are fewer than ``MIN_DIFFERENCES`` windows."""
    count = rows - NOISE_WINDOW + 1
    if count < MIN_DIFFERENCES:
        return np.full(3, np.nan)
    window = np.arange(count)[:, None] + np.arange(NOISE_WINDOW)
    u = (track.tau[window] - track.tau[window[:, :1]]) / track.unit
    basis = _basis(u)
    ys = track.pose[window]
    fits = _Fits(np.einsum("pki,pkj->pij", basis, basis), np.einsum("pki,pkc->pic", basis, ys), 0.0)
    fitted = fits.b0[:, None] + u[..., None] * fits.b1[:, None] + 0.5 * (u * u)[..., None] * fits.b2[:, None]
    dof = NOISE_WINDOW - 3
    median_chi2 = dof * (1.0 - 2.0 / (9.0 * dof)) ** 3  # Wilson-Hilferty
    return np.sqrt(np.median(((ys - fitted) ** 2).sum(axis=1), axis=0) / median_chi2)


def segment_track(t, x, y, phi, usable, *, sides, circumradius, g=9.81, noise=None, table=0.0):
    """Free flights of one track, with the glitches skipped and the noise used.

    Parameters are those of :func:`find_flights`. Without ``noise``, the track's own is used:
    the scatter about ballistic fits over windows of ``NOISE_WINDOW`` frames before the
    sustained contact, kept between 1 and ``WINDOW_EXCESS`` times :func:`difference_noise` of
    those frames. On the shared data the windows scatter more than the differences say: the
    tracking errors last a few frames, and a moving die is tracked worse than one at rest.

    Returns
    -------
    Segmentation
    """
    t, x, y, phi = (np.asarray(a, dtype=float) for a in (t, x, y, phi))
    given = noise is not None
    if not given:
        noise = difference_noise(t, x, y, phi, usable, circumradius=circumradius)
    track = _Track(t, x, y, phi, usable, sides, circumradius, g, noise, table)
    if not given and np.isfinite(track.var).all() and track.count >= MIN_FLIGHT_FRAMES:
        # the noise of the moving die (a die at rest is tracked better: no blur)
        moving = _sustained_contact(track, max(MIN_FLIGHT_FRAMES, int(round(CONTACT_TIME / track.dt))))
        frames = track.index[:moving]
        own = difference_noise(t[frames], x[frames], y[frames], phi[frames], np.ones(frames.size, dtype=bool), circumradius=circumradius)
        base = np.where(np.isfinite(own), own, track.noise)
        scatter = _window_noise(track, moving) * [1.0, 1.0, 1.0 / circumradius]
        track.set_noise(np.clip(np.where(np.isfinite(scatter), scatter, base), base, WINDOW_EXCESS * base))
    found, outliers, stop = _segment(track)
    mask = np.zeros(t.size, dtype=bool)
    for first, last in found:
        mask[track.index[first : last + 1][outliers[first : last + 1]]] = True
    flights = [(int(track.index[first]), int(track.index[last])) for first, last in found]
    contact = int(track.index[stop]) if stop < track.count else None
    return Segmentation(flights, mask, track.noise, track.band, contact)


def find_flights(t, x, y, phi, usable, *, sides, circumradius, g=9.81, noise=None, table=0.0):
    """Free flights of one track: inclusive (first, last) frame indices, in time order.

    A flight is a run of usable frames over which x and phi are linear in t and y is a parabola
    of curvature -g, to within the noise (and ``CURVATURE_TOLERANCE`` g), with the fitted lowest
    corner clear of the table. Flights are separated by impacts; frames around an impact (in
    the contact band) belong to none. Flights shorter than ``MIN_FLIGHT_FRAMES`` usable frames
    are left out (the next flight is then after them). The track ends at sustained contact
    (rocking, sliding, rest). The module docstring gives the tests.

    Parameters
    ----------
    t : numpy.ndarray
        Times, s, ascending (steps of several frames are fine).
    x, y : numpy.ndarray
        Geometric centre, m: horizontal position and height above the table.
    phi : numpy.ndarray
        Angle of corner 0, rad, counterclockwise (model convention), unwrapped.
    usable : numpy.ndarray of bool
        Frames with a complete pose that are not known glitches (NaN rows are left out too).
    sides : int
        n of the die.
    circumradius : float
        R, m.
    g : float
        m/s^2.
    noise : sequence of 3 float, optional
        Tracking noise sigma of x, y (m) and phi (rad), e.g. :func:`estimate_noise` of the
        track's set. Default: estimated from the track itself (:func:`segment_track`). On
        measured data pass the set's: one track's estimate is mostly its slow frames, and the
        fast first fall may be tracked worse (blur).
    table : float
        Height of the table in the track's frame, m (e.g.
        :func:`dice_sweep.measured.impacts.table_level` of the dice at rest).

    Returns
    -------
    list of (int, int)
        Indices into ``t`` of each flight's first and last frame. Usable frames inside a flight
        that its fit skipped as glitches are given by :func:`segment_track`.
    """
    return segment_track(t, x, y, phi, usable, sides=sides, circumradius=circumradius, g=g, noise=noise, table=table).flights


# --- noise over many tracks ----------------------------------------------------------------


def _track_arrays(item):
    """(t, x, y, phi, usable) of a Track-like object or a tuple."""
    if hasattr(item, "t"):
        return item.t, item.x, item.y, item.phi, item.usable
    return tuple(item)


def estimate_noise(tracks, *, sides, circumradius, g=9.81, table=0.0, noise=None, samples=BOOTSTRAP_SAMPLES, seed=0):
    """Tracking noise of x, y and phi from the residuals of ballistic fits over free flights.

    The flights are found by :func:`segment_track` (with ``noise``, or each track's own).
    Each flight's usable frames (glitches skipped; frames whose fitted lowest corner is within
    ``NOISE_CLEARANCE`` sigma of the contact band left out, as the contact tests picked them
    by their own noise) are then fitted on their own: a quadratic in t for each of x, y and
    R phi. A coordinate's variance is the sum of its squared residuals over the sum of the
    degrees of freedom (frames less ``FIT_PARAMETERS``), pooled over tracks; its 95 % interval
    comes from a bootstrap over tracks, the independent units.

    Parameters
    ----------
    tracks : iterable
        :class:`dice_sweep.measured.tracks.Track` objects, or (t, x, y, phi, usable) tuples.
    sides, circumradius, g, table
        As for :func:`find_flights`.
    noise : sequence of 3 float, optional
        Noise for the segmentation (x, y in m, phi in rad); default: each track's own.
    samples : int
        Bootstrap resamples.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    NoiseEstimate
        NaN sigmas when no track has a flight with spare degrees of freedom.
    """
    rss, dof, flights, frames = [], [], 0, 0
    for item in tracks:
        t, x, y, phi, usable = (np.asarray(a) for a in _track_arrays(item))
        seg = segment_track(t, x, y, phi, usable, sides=sides, circumradius=circumradius, g=g, noise=noise, table=table)
        pose = np.column_stack((x, y, circumradius * phi))
        groups = [rows for rows in seg.flight_frames(usable) if rows.size >= MIN_FLIGHT_FRAMES]
        groups = _clear_rows(t, pose, groups, seg, sides, circumradius, table)
        r, d = _residual_sums(t, pose, groups)
        if d.min() > 0:
            rss.append(r)
            dof.append(d)
            flights += len(groups)
            frames += sum(rows.size for rows in groups)
    if not rss:
        nan3 = np.full(3, np.nan)
        return NoiseEstimate(nan3, np.full((3, 2), np.nan), math.nan, (math.nan, math.nan), 0, 0, 0, np.zeros(3))
    rss, dof = np.array(rss), np.array(dof)
    scale = np.array([1.0, 1.0, 1.0 / circumradius])
    sigma = np.sqrt(rss.sum(axis=0) / dof.sum(axis=0)) * scale
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(len(rss), np.full(len(rss), 1.0 / len(rss)), size=samples).astype(float)
    boot = np.sqrt((counts @ rss) / (counts @ dof)) * scale  # (samples, 3)
    tail = 50.0 * (1.0 - CONFIDENCE)
    interval = np.percentile(boot, [tail, 100.0 - tail], axis=0).T
    pose_boot = np.sqrt(boot[:, 0] ** 2 + boot[:, 1] ** 2 + (circumradius * boot[:, 2]) ** 2)
    pose = float(math.sqrt(sigma[0] ** 2 + sigma[1] ** 2 + (circumradius * sigma[2]) ** 2))
    pose_interval = tuple(float(v) for v in np.percentile(pose_boot, [tail, 100.0 - tail]))
    return NoiseEstimate(sigma, interval, pose, pose_interval, len(rss), flights, frames, dof.sum(axis=0))
