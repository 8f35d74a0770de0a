"""Numbers for the chaos of a final-state map, and what a thrower of given precision controls.

Measures of an outcome map (issue 6, docs/chaos.md):

- outcome fractions per side, with the undecided share;
- basin entropy Sb and boundary basin entropy Sbb (Daza, Wagemakers, Georgeot,
  Guery-Odelin, Sanjuan, Sci. Rep. 6, 31416 (2016)) on boxes of ``box_size`` x ``box_size``
  pixels, and their log 2 criterion (Sbb > ln 2 proves a fractal boundary);
- the uncertainty exponent alpha (Grebogi, McDonald, Ott, Yorke, Phys. Lett. A 99, 415
  (1983)): the share f(eps) of pixels whose outcome changes when the start moves by eps
  pixels, f ~ eps^alpha, fitted where the power law holds. The boundary's box-counting
  dimension is D = 2 - alpha; alpha = 1 for a smooth boundary, alpha -> 0 for a riddled map.

Every outcome code is a colour of its own, the undecided code -1 included: a region of
undecided rolls is a basin of "no answer".

Measures of a probability map (a sweep of M draws per pixel under the stochastic impact law,
issue 31): the predictable share (pixels where one side has p >= 0.9), with the range the M
draws leave it, and the basin entropy as the mean outcome entropy of the pixels (:func:`measure_probability`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from dice_sweep.errors import DiceSweepError

DEFAULT_BOX_SIZE = 5  # pixels per box side for Sb and Sbb, as in Daza et al. 2016
LOG2 = math.log(2.0)  # Sbb above this proves a fractal boundary (Daza et al. 2016)
SMOOTH_BOUNDARY_SBB = 0.5  # Sbb of a smooth two-basin boundary: mean binary entropy of a uniform share
UNDECIDED = -1

PREDICTABLE_PROBABILITY = 0.9  # a pixel where one side has at least this probability is predictable
Z95 = 1.959963984540054  # two-sided 95 % normal quantile, for the Wilson bounds of a pixel's shares

# Uncertainty exponent
EPS_POINTS = 16  # log-spaced perturbations tried, before rounding to whole pixels
EPS_MAX_SHARE = 1 / 8  # the largest perturbation, as a share of the shorter side of the map
MIN_UNCERTAIN_PIXELS = 20  # fewer uncertain pixels than this: f(eps) too noisy to fit
FIT_MIN_POINTS = 4  # a power-law range holds at least this many perturbations ...
FIT_MIN_SPAN = 4.0  # ... spanning at least this factor in eps
FIT_MAX_RESIDUAL = 0.1  # largest |ln f - fit| inside the power-law range (10 % in f)
F_SATURATED = 0.5  # above this f flattens towards 1 whatever the boundary: left out of fits


# --- outcome fractions --------------------------------------------------------------------


def outcome_fractions(outcome, sides) -> dict[int, float]:
    """Share of pixels per outcome.

    Parameters
    ----------
    outcome : array_like of int
        Outcome map: side 0..n-1, -1 undecided.
    sides : int
        Number of sides n.

    Returns
    -------
    dict of int to float
        Outcome -> share of pixels, for -1 (undecided) and every side 0..n-1; sums to 1.
    """
    outcome = np.asarray(outcome)
    counts = np.bincount(outcome.ravel().astype(np.int64) + 1, minlength=sides + 1)
    return {code - 1: count / outcome.size for code, count in enumerate(counts)}


# --- basin entropy ------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class BasinEntropy:
    """Basin entropy Sb and boundary basin entropy Sbb of a map (Daza et al. 2016).

    Attributes
    ----------
    box_size : int
        Side of a box, pixels.
    sb : float
        Mean Gibbs entropy of the boxes, nats (0 .. ln of the number of outcomes).
    sbb : float
        Mean entropy of the boxes holding more than one outcome (boundary boxes), nats; NaN
        if there is none.
    boxes, boundary_boxes : int
        Number of boxes and of boundary boxes.
    used_shape : tuple of int
        (rows, columns) of pixels covered by whole boxes; the rest (the top rows and right
        columns of the map) is left out.
    box_entropy : numpy.ndarray
        float (rows // box_size, columns // box_size): entropy of each box, nats.
    """

    box_size: int
    sb: float
    sbb: float
    boxes: int
    boundary_boxes: int
    used_shape: tuple[int, int]
    box_entropy: np.ndarray

    @property
    def fractal_by_log2(self) -> bool:
        """True if Sbb > ln 2: the boundary is fractal (sufficient, not necessary)."""
        return bool(self.sbb > LOG2)

    def to_dict(self) -> dict:
        """The numbers, JSON-ready (without the box map)."""
        return {
            "box_size_pixels": self.box_size,
            "Sb": self.sb,
            "Sbb": _json_float(self.sbb),
            "boxes": self.boxes,
            "boundary_boxes": self.boundary_boxes,
            "used_shape": list(self.used_shape),
            "Sbb_above_log2": self.fractal_by_log2,
        }


def basin_entropy(outcome, box_size: int = DEFAULT_BOX_SIZE) -> BasinEntropy:
    """Sb and Sbb of an outcome map on boxes of ``box_size`` x ``box_size`` pixels.

    The map is covered by whole boxes from its first row and column (``y`` and ``x`` at their
    minimum); when a side is not divisible by ``box_size`` the remaining top rows and right
    columns (fewer than ``box_size``) are left out. In box i the share p_ij of each outcome j
    gives the entropy S_i = -sum_j p_ij ln p_ij. Sb is the mean of S_i over all boxes, Sbb the
    mean over the boxes holding more than one outcome.

    Parameters
    ----------
    outcome : array_like of int, shape (ny, nx)
        Outcome map; every code (-1 undecided included) is an outcome.
    box_size : int
        Box side in pixels (Daza et al. use 5).

    Returns
    -------
    BasinEntropy

    Raises
    ------
    DiceSweepError
        If ``box_size`` < 1 or larger than the map.
    """
    outcome = np.asarray(outcome)
    box_size = int(box_size)
    if box_size < 1 or box_size > min(outcome.shape):
        raise DiceSweepError(f"--box-size {box_size}: need 1 <= box size <= {min(outcome.shape)} (the map's shorter side)")
    rows, cols = (length // box_size for length in outcome.shape)
    used = outcome[: rows * box_size, : cols * box_size]
    boxes = used.reshape(rows, box_size, cols, box_size).swapaxes(1, 2).reshape(rows, cols, box_size**2)
    entropy = np.zeros((rows, cols))
    for code in np.unique(boxes):
        share = (boxes == code).mean(axis=-1)
        entropy -= np.where(share > 0, share * np.log(np.where(share > 0, share, 1.0)), 0.0)
    entropy = np.maximum(entropy, 0.0)  # -0.0 and round-off of single-outcome boxes
    boundary = (boxes != boxes[..., :1]).any(axis=-1)
    return BasinEntropy(
        box_size=box_size,
        sb=float(entropy.mean()),
        sbb=float(entropy[boundary].mean()) if boundary.any() else math.nan,
        boxes=entropy.size,
        boundary_boxes=int(boundary.sum()),
        used_shape=(rows * box_size, cols * box_size),
        box_entropy=entropy,
    )


# --- uncertainty exponent -----------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class PowerLawFit:
    """f = c eps^alpha fitted on a range of perturbations.

    Attributes
    ----------
    alpha : float
        Fitted exponent (NaN if nothing could be fitted).
    alpha_err : float
        Its uncertainty: the larger of the least-squares standard error and half the
        difference between the slopes of the two halves of the range (a drift of the local
        slope is a systematic error the standard error does not see); NaN from 2 points.
    log_prefactor : float
        ln c.
    eps_lo, eps_hi : float
        The range of eps (pixels) where the power law holds within ``FIT_MAX_RESIDUAL``.
    points : int
        Perturbations in the range.
    power_law : bool
        False if no range of ``FIT_MIN_POINTS`` points spanning ``FIT_MIN_SPAN`` fits within
        ``FIT_MAX_RESIDUAL``; the fit is then over every usable point and only indicative.
    saturated : bool
        True if f > ``F_SATURATED`` at all perturbations but at most one: the map is mixed down to the
        pixel, and alpha near 0 says only that f no longer falls within the resolved scales.
    """

    alpha: float
    alpha_err: float
    log_prefactor: float
    eps_lo: float
    eps_hi: float
    points: int
    power_law: bool
    saturated: bool = False

    def text(self) -> str:
        """``"0.931 ± 0.022"``, or ``"0.551 from 2 points"``, with ``(saturated)`` or
        ``(no clean power law)`` when the fit is so marked."""
        error = f"± {self.alpha_err:.3f}" if math.isfinite(self.alpha_err) else f"from {self.points} points"
        text = f"{self.alpha:.3f} {error}"
        if self.saturated:
            return text + " (saturated)"
        return text if self.power_law else text + " (no clean power law)"


def _slope(log_eps, log_f):
    """(slope, intercept, standard error of the slope) of a least-squares line (NaN error for 2 points)."""
    slope, intercept = np.polyfit(log_eps, log_f, 1)
    if len(log_eps) < 3:
        return slope, intercept, math.nan
    residuals = log_f - (slope * log_eps + intercept)
    spread = np.sum((log_eps - log_eps.mean()) ** 2)
    return slope, intercept, math.sqrt(np.sum(residuals**2) / (len(log_eps) - 2) / spread)


def _fit_window(log_eps, log_f) -> tuple[float, float, float, float]:
    """(alpha, alpha_err, ln c, max |residual|) of one window of points."""
    slope, intercept, stderr = _slope(log_eps, log_f)
    half = len(log_eps) // 2
    if half >= 2:
        drift = abs(_slope(log_eps[:half], log_f[:half])[0] - _slope(log_eps[-half:], log_f[-half:])[0]) / 2
    else:
        drift = 0.0
    worst = float(np.max(np.abs(log_f - (slope * log_eps + intercept))))
    return float(slope), float(max(stderr, drift)) if math.isfinite(stderr) else math.nan, float(intercept), worst


def fit_power_law(eps, fraction, uncertain_pixels=None) -> PowerLawFit:
    """Fit f = c eps^alpha on the widest range of eps where a power law holds.

    Usable points have f > 0, f <= ``F_SATURATED`` (as f nears 1 it flattens whatever the
    boundary; if fewer than 2 points are that low, the saturated ones are used and the fit is
    marked ``saturated``) and, if given, at least ``MIN_UNCERTAIN_PIXELS`` uncertain pixels.
    Candidate ranges are runs of at least ``FIT_MIN_POINTS`` consecutive usable points
    spanning a factor ``FIT_MIN_SPAN`` in eps. Among those whose largest residual
    |ln f - fit| is at most ``FIT_MAX_RESIDUAL``, the one with most points wins (ties:
    smallest residual).

    Parameters
    ----------
    eps : array_like of float
        Perturbations, increasing.
    fraction : array_like of float
        f(eps).
    uncertain_pixels : array_like of int, optional
        Number of uncertain pixels behind each f (to leave out noisy points).

    Returns
    -------
    PowerLawFit
    """
    eps = np.asarray(eps, dtype=float)
    fraction = np.asarray(fraction, dtype=float)
    usable = fraction > 0
    if uncertain_pixels is not None:
        usable &= np.asarray(uncertain_pixels) >= MIN_UNCERTAIN_PIXELS
    saturated = bool((usable & (fraction <= F_SATURATED)).sum() < 2)
    if not saturated:
        usable &= fraction <= F_SATURATED
    log_eps, log_f = np.log(eps[usable]), np.log(fraction[usable])
    if len(log_eps) < 2:
        return PowerLawFit(math.nan, math.nan, math.nan, math.nan, math.nan, 0, False)
    best = None  # (points, -worst residual, fit, lo, hi)
    for lo in range(len(log_eps)):
        for hi in range(lo + FIT_MIN_POINTS, len(log_eps) + 1):
            if log_eps[hi - 1] - log_eps[lo] < math.log(FIT_MIN_SPAN):
                continue
            fit = _fit_window(log_eps[lo:hi], log_f[lo:hi])
            key = (hi - lo, -fit[3])
            if fit[3] <= FIT_MAX_RESIDUAL and (best is None or key > best[0]):
                best = (key, fit, lo, hi)
    if best is None:
        alpha, alpha_err, intercept, _ = _fit_window(log_eps, log_f)
        lo, hi, power_law = 0, len(log_eps), False
    else:
        _, (alpha, alpha_err, intercept, _), lo, hi = best
        power_law = True
    used_eps = eps[usable]
    return PowerLawFit(
        alpha, alpha_err, intercept, float(used_eps[lo]), float(used_eps[hi - 1]), hi - lo, power_law, saturated
    )


def default_perturbations(shape) -> np.ndarray:
    """Whole-pixel perturbations, log-spaced from 1 to ``EPS_MAX_SHARE`` of the shorter side.

    Parameters
    ----------
    shape : tuple of int
        (ny, nx) of the map.

    Returns
    -------
    numpy.ndarray
        int64, increasing, unique (at most ``EPS_POINTS``).
    """
    largest = max(1, int(min(shape) * EPS_MAX_SHARE))
    return np.unique(np.round(np.logspace(0.0, math.log10(largest), EPS_POINTS)).astype(np.int64))


@dataclasses.dataclass(frozen=True)
class UncertaintyCurve:
    """The uncertain share f(eps) of a map and its power-law fit.

    Attributes
    ----------
    eps : numpy.ndarray
        int (k,): perturbations in pixels (the same number of pixels along both axes).
    fraction : numpy.ndarray
        float (k,): share of the tested pixels whose outcome differs from that of at least one
        of the four starts eps pixels away (left, right, below, above).
    uncertain_pixels : numpy.ndarray
        int (k,): number of such pixels.
    tested_pixels : int
        Pixels tested for every eps: all those at least ``max(eps)`` pixels from every edge,
        the same set for every eps, so that f(eps) is a power law wherever the boundary is.
    fit : PowerLawFit
    """

    eps: np.ndarray
    fraction: np.ndarray
    uncertain_pixels: np.ndarray
    tested_pixels: int
    fit: PowerLawFit

    @property
    def dimension(self) -> float:
        """Box-counting dimension of the boundary in the plane, 2 - alpha."""
        return 2.0 - self.fit.alpha

    def local_slopes(self) -> np.ndarray:
        """d ln f / d ln eps between consecutive perturbations (NaN where f = 0)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.diff(np.log(self.fraction)) / np.diff(np.log(self.eps))

    def to_dict(self, x_step=None, y_step=None) -> dict:
        """The curve and fit, JSON-ready; eps also in the axes' units if the steps are given."""
        fit = self.fit
        result = {
            "eps_pixels": self.eps.tolist(),
            "fraction": self.fraction.tolist(),
            "uncertain_pixels": self.uncertain_pixels.tolist(),
            "tested_pixels": self.tested_pixels,
            "alpha": _json_float(fit.alpha),
            "alpha_err": _json_float(fit.alpha_err),
            "boundary_dimension": _json_float(self.dimension),
            "power_law": fit.power_law,
            "saturated": fit.saturated,
            "fit_eps_pixels": [_json_float(fit.eps_lo), _json_float(fit.eps_hi)],
            "fit_points": fit.points,
        }
        if x_step is not None and y_step is not None:
            result["eps_x_per_pixel"] = x_step
            result["eps_y_per_pixel"] = y_step
        return result


def uncertain_pixels(outcome, eps: int, margin: int) -> np.ndarray:
    """bool map of the pixels at least ``margin`` from every edge whose outcome is uncertain.

    A pixel is uncertain at perturbation ``eps`` if a start ``eps`` pixels to its left,
    right, below or above ends differently.

    Parameters
    ----------
    outcome : numpy.ndarray, shape (ny, nx)
    eps : int
        Perturbation, pixels; at most ``margin``.
    margin : int
        Pixels left out at every edge.

    Returns
    -------
    numpy.ndarray
        bool (ny - 2 margin, nx - 2 margin).
    """
    ny, nx = outcome.shape
    centre = outcome[margin : ny - margin, margin : nx - margin]
    uncertain = np.zeros(centre.shape, dtype=bool)
    for dy, dx in ((eps, 0), (-eps, 0), (0, eps), (0, -eps)):
        uncertain |= outcome[margin + dy : ny - margin + dy, margin + dx : nx - margin + dx] != centre
    return uncertain


def uncertainty_curve(outcome, eps=None) -> UncertaintyCurve:
    """f(eps) of an outcome map over ``eps`` and its power-law fit (:func:`fit_power_law`).

    Parameters
    ----------
    outcome : array_like of int, shape (ny, nx)
    eps : array_like of int, optional
        Perturbations in pixels; default :func:`default_perturbations`.

    Returns
    -------
    UncertaintyCurve

    Raises
    ------
    DiceSweepError
        If the map is too small for the largest perturbation.
    """
    outcome = np.asarray(outcome)
    eps = default_perturbations(outcome.shape) if eps is None else np.asarray(eps, dtype=np.int64)
    margin = int(eps.max())
    if eps.min() < 1 or 2 * margin >= min(outcome.shape):
        raise DiceSweepError(f"map {outcome.shape[0]} x {outcome.shape[1]}: too small for perturbations of 1 .. {margin} pixels")
    counts = np.array([uncertain_pixels(outcome, int(e), margin).sum() for e in eps])
    tested = (outcome.shape[0] - 2 * margin) * (outcome.shape[1] - 2 * margin)
    fraction = counts / tested
    return UncertaintyCurve(eps, fraction, counts, tested, fit_power_law(eps, fraction, counts))


# --- probability maps ---------------------------------------------------------------------


def shannon_entropy(shares, axis=0) -> np.ndarray:
    """-sum_k p_k ln p_k over ``axis`` (nats; 0 ln 0 = 0): ln n for n equally likely outcomes."""
    p = np.asarray(shares, dtype=np.float64)
    return np.maximum(-np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0), axis=axis), 0.0)


def wilson_bounds(share, count, z=Z95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score bounds (low, high) of binomial shares observed in ``count`` trials (arrays)."""
    p = np.asarray(share, dtype=np.float64)
    centre = (p + z * z / (2 * count)) / (1 + z * z / count)
    half = z * np.sqrt(p * (1 - p) / count + z * z / (4 * count * count)) / (1 + z * z / count)
    return np.clip(centre - half, 0.0, 1.0), np.clip(centre + half, 0.0, 1.0)


@dataclasses.dataclass(frozen=True)
class ProbabilityMeasures:
    """What a probability map says about predictability (:func:`measure_probability`).

    Attributes
    ----------
    draws : int
        Rolls per pixel, M.
    shape : tuple of int
        (ny, nx).
    predictable : float
        Share of pixels whose most likely side has an estimated p >= PREDICTABLE_PROBABILITY.
    predictable_range : tuple of float
        (surely, possibly): the shares of pixels where some side's 95 % Wilson bound from the
        M draws is >= PREDICTABLE_PROBABILITY, lower bound and upper bound: how far the M
        draws leave the predictable share open.
    entropy_map : numpy.ndarray
        float (ny, nx): each pixel's outcome entropy over the n sides and no answer, nats.
    basin_entropy : float
        Mean of ``entropy_map``, nats: the basin entropy with each pixel's draws as its box.
    basin_entropy_corrected : float
        The same with each pixel's Miller-Madow correction, (outcomes seen - 1) / (2 M) nats:
        the plug-in entropy of M draws is biased low by about that much.
    no_answer : float
        Mean share of draws without a side.
    """

    draws: int
    shape: tuple[int, int]
    predictable: float
    predictable_range: tuple[float, float]
    entropy_map: np.ndarray
    basin_entropy: float
    basin_entropy_corrected: float
    no_answer: float

    def to_dict(self) -> dict:
        """The numbers, JSON-ready (without the entropy map)."""
        return {
            "draws": self.draws,
            "predictable_probability": PREDICTABLE_PROBABILITY,
            "predictable_share": self.predictable,
            "predictable_share_range_from_draws": list(self.predictable_range),
            "basin_entropy_nats": self.basin_entropy,
            "basin_entropy_miller_madow_nats": self.basin_entropy_corrected,
            "no_answer_share": self.no_answer,
        }

    def describe(self) -> str:
        """Two lines for the user."""
        low, high = self.predictable_range
        return "\n".join([
            f"probability map from {self.draws} draws per pixel: predictable (one side p >= {PREDICTABLE_PROBABILITY:g}) "
            f"{self.predictable:.4f} of the pixels, {low:.4f} .. {high:.4f} within the draws' 95 % Wilson bounds",
            f"basin entropy (mean outcome entropy per pixel, Daza et al. 2016) {self.basin_entropy:.4f} nats "
            f"({self.basin_entropy_corrected:.4f} Miller-Madow corrected); no answer {self.no_answer:.4f} of the draws",
        ])


def measure_probability(probability, draws: int) -> ProbabilityMeasures:
    """Predictable share and basin entropy of a probability map.

    Parameters
    ----------
    probability : array_like of float, shape (n + 1, ny, nx)
        Row k < n: share of a pixel's draws ending on side k; row n: share without a side
        (as :attr:`dice_sweep.storage.SweepData.probability`).
    draws : int
        Draws per pixel, M.

    Returns
    -------
    ProbabilityMeasures
    """
    p = np.asarray(probability, dtype=np.float64)
    sides = p[:-1]
    low, high = wilson_bounds(sides, draws)
    entropy = shannon_entropy(p)
    seen = (p > 0).sum(axis=0)
    return ProbabilityMeasures(
        draws=int(draws),
        shape=p.shape[1:],
        predictable=float((sides.max(axis=0) >= PREDICTABLE_PROBABILITY).mean()),
        predictable_range=(float((low.max(axis=0) >= PREDICTABLE_PROBABILITY).mean()),
                           float((high.max(axis=0) >= PREDICTABLE_PROBABILITY).mean())),
        entropy_map=entropy,
        basin_entropy=float(entropy.mean()),
        basin_entropy_corrected=float((entropy + (seen - 1) / (2.0 * draws)).mean()),
        no_answer=float(p[-1].mean()),
    )


# --- all measures of a map ----------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ChaosMeasures:
    """Every measure of one outcome map (:func:`measure_map`, :func:`measure_file`).

    Attributes
    ----------
    sides : int
    shape : tuple of int
        (ny, nx).
    fractions : dict of int to float
        Share of pixels per outcome (-1 undecided).
    entropy : BasinEntropy
    uncertainty : UncertaintyCurve
    x_step, y_step : float or None
        Cell widths of the axes (their SI units), to state eps physically.
    probability : ProbabilityMeasures or None
        Of a probability map (M draws per pixel); the map measures above are then of draw 0.
    """

    sides: int
    shape: tuple[int, int]
    fractions: dict[int, float]
    entropy: BasinEntropy
    uncertainty: UncertaintyCurve
    x_step: float | None = None
    y_step: float | None = None
    probability: ProbabilityMeasures | None = None

    def to_dict(self) -> dict:
        """All numbers, JSON-ready."""
        return {
            "sides": self.sides,
            "shape": list(self.shape),
            "fractions": {("undecided" if k == UNDECIDED else str(k)): v for k, v in self.fractions.items()},
            "basin_entropy": self.entropy.to_dict(),
            "uncertainty": self.uncertainty.to_dict(self.x_step, self.y_step),
            **({"probability": self.probability.to_dict()} if self.probability is not None else {}),
        }

    def describe(self) -> str:
        """A few lines for the user."""
        entropy, fit = self.entropy, self.uncertainty.fit
        sides = ", ".join(f"{k}: {v:.3f}" for k, v in self.fractions.items() if k != UNDECIDED)
        law = "power law" if fit.power_law else "no clean power law: fit over all usable points"
        if fit.saturated:
            law = f"saturated: f > {F_SATURATED:g} already at the smallest eps"
        draw0 = "" if self.probability is None else " (draw 0 of each pixel)"
        return "\n".join(
            [
                f"map {self.shape[0]} x {self.shape[1]}{draw0}, n = {self.sides}; undecided {self.fractions[UNDECIDED]:.4f}",
                f"fractions: {sides}",
                f"Sb = {entropy.sb:.4f}, Sbb = {entropy.sbb:.4f} nats on {entropy.box_size} x {entropy.box_size} boxes "
                f"({entropy.boundary_boxes} of {entropy.boxes} on a boundary); "
                f"Sbb {'>' if entropy.fractal_by_log2 else '<='} ln 2 = {LOG2:.4f}",
                f"uncertainty exponent alpha = {fit.text()} "
                f"({law}; eps {fit.eps_lo:g} .. {fit.eps_hi:g} pixels, {fit.points} points); "
                f"boundary dimension {self.uncertainty.dimension:.3f}",
                *([] if self.probability is None else [self.probability.describe()]),
            ]
        )


def measure_map(outcome, sides, box_size=DEFAULT_BOX_SIZE, eps=None, *, x_step=None, y_step=None, probability=None,
                draws=1) -> ChaosMeasures:
    """Outcome fractions, Sb, Sbb and the uncertainty exponent of an outcome map.

    Parameters
    ----------
    outcome : array_like of int, shape (ny, nx)
        Side 0..n-1 or -1 (undecided).
    sides : int
        Number of sides n.
    box_size : int
        Box side for Sb and Sbb, pixels.
    eps : array_like of int, optional
        Perturbations for f(eps), pixels.
    x_step, y_step : float, optional
        Cell widths, to report eps in the axes' units.
    probability : array_like, optional
        (n + 1, ny, nx) shares of a probability map of ``draws`` draws per pixel
        (:func:`measure_probability`).

    Returns
    -------
    ChaosMeasures
    """
    outcome = np.asarray(outcome)
    return ChaosMeasures(
        sides=int(sides),
        shape=outcome.shape,
        fractions=outcome_fractions(outcome, sides),
        entropy=basin_entropy(outcome, box_size),
        uncertainty=uncertainty_curve(outcome, eps),
        x_step=x_step,
        y_step=y_step,
        probability=None if probability is None else measure_probability(probability, draws),
    )


def _json_float(value):
    """A float for JSON: NaN becomes None (JSON has no NaN)."""
    return None if value is None or not math.isfinite(value) else float(value)
