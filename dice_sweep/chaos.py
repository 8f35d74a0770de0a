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

Control maps: a thrower whose initial values scatter with standard deviations sigma gets
each side with a probability that depends on the aimed point. It is the Gaussian blur of the
side's indicator on a fine map, or, where the map is too coarse for that (or a scattered
value is not an axis of the map), the share of Monte Carlo rolls that land on the side.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib

import numpy as np

from dice_sweep.config import GRID_PARAMS, PARAM_UNITS
from dice_sweep.errors import DiceSweepError
from dice_sweep.outputs import FOLDER, JSON, NPZ, check_outputs

DEFAULT_BOX_SIZE = 5  # pixels per box side for Sb and Sbb, as in Daza et al. 2016
LOG2 = math.log(2.0)  # Sbb above this proves a fractal boundary (Daza et al. 2016)
SMOOTH_BOUNDARY_SBB = 0.5  # Sbb of a smooth two-basin boundary: mean binary entropy of a uniform share
UNDECIDED = -1

# Uncertainty exponent
EPS_POINTS = 16  # log-spaced perturbations tried, before rounding to whole pixels
EPS_MAX_SHARE = 1 / 8  # the largest perturbation, as a share of the shorter side of the map
MIN_UNCERTAIN_PIXELS = 20  # fewer uncertain pixels than this: f(eps) too noisy to fit
FIT_MIN_POINTS = 4  # a power-law range holds at least this many perturbations ...
FIT_MIN_SPAN = 4.0  # ... spanning at least this factor in eps
FIT_MAX_RESIDUAL = 0.1  # largest |ln f - fit| inside the power-law range (10 % in f)
F_SATURATED = 0.5  # above this f flattens towards 1 whatever the boundary: left out of fits

# Control maps
BLUR_MIN_PIXELS = 2.0  # the blur needs sigma at least this many cells wide on a blurred axis
BLUR_TRUNCATE = 4.0  # the Gaussian kernel is cut at this many sigma
DEFAULT_SAMPLES = 256  # Monte Carlo rolls per point
DEFAULT_MC_POINTS = 64  # Monte Carlo points per axis, at most
CONTROLLED_PROBABILITY = 0.9  # a point where one side has at least this probability is "controlled"
START_DRAWS = 100  # redraws of a Monte Carlo start that put a corner inside a surface
MAX_SIGMA = 1e300  # --sigma: a larger one overflows the Monte Carlo draws to inf
MAX_MC_ROLLS = 10_000_000  # Monte Carlo rolls of one control map: their starts are held in memory (~200 B each)


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
    """

    sides: int
    shape: tuple[int, int]
    fractions: dict[int, float]
    entropy: BasinEntropy
    uncertainty: UncertaintyCurve
    x_step: float | None = None
    y_step: float | None = None

    def to_dict(self) -> dict:
        """All numbers, JSON-ready."""
        return {
            "sides": self.sides,
            "shape": list(self.shape),
            "fractions": {("undecided" if k == UNDECIDED else str(k)): v for k, v in self.fractions.items()},
            "basin_entropy": self.entropy.to_dict(),
            "uncertainty": self.uncertainty.to_dict(self.x_step, self.y_step),
        }

    def describe(self) -> str:
        """A few lines for the user."""
        entropy, fit = self.entropy, self.uncertainty.fit
        sides = ", ".join(f"{k}: {v:.3f}" for k, v in self.fractions.items() if k != UNDECIDED)
        law = "power law" if fit.power_law else "no clean power law: fit over all usable points"
        if fit.saturated:
            law = f"saturated: f > {F_SATURATED:g} already at the smallest eps"
        return "\n".join(
            [
                f"map {self.shape[0]} x {self.shape[1]}, n = {self.sides}; undecided {self.fractions[UNDECIDED]:.4f}",
                f"fractions: {sides}",
                f"Sb = {entropy.sb:.4f}, Sbb = {entropy.sbb:.4f} nats on {entropy.box_size} x {entropy.box_size} boxes "
                f"({entropy.boundary_boxes} of {entropy.boxes} on a boundary); "
                f"Sbb {'>' if entropy.fractal_by_log2 else '<='} ln 2 = {LOG2:.4f}",
                f"uncertainty exponent alpha = {fit.text()} "
                f"({law}; eps {fit.eps_lo:g} .. {fit.eps_hi:g} pixels, {fit.points} points); "
                f"boundary dimension {self.uncertainty.dimension:.3f}",
            ]
        )


def measure_map(outcome, sides, box_size=DEFAULT_BOX_SIZE, eps=None, *, x_step=None, y_step=None) -> ChaosMeasures:
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
    )


def _cell_width(axis) -> float:
    return (axis.hi - axis.lo) / len(axis.values)


def read_complete_sweep(path):
    """:func:`dice_sweep.storage.read_sweep`, refusing a file with cells not computed.

    Raises
    ------
    DiceSweepError
        If some cell was never computed (an interrupted sweep).
    """
    from dice_sweep.storage import read_sweep

    sweep = read_sweep(path)
    missing = int((~sweep.computed).sum())
    if missing:
        raise DiceSweepError(f"{path}: {missing} cells not computed; finish the sweep with --resume first")
    return sweep


def measure_file(path, box_size=DEFAULT_BOX_SIZE) -> ChaosMeasures:
    """:func:`measure_map` of a complete sweep file (docs/hdf5.md).

    Parameters
    ----------
    path : str or os.PathLike
        Sweep file.
    box_size : int
        Box side for Sb and Sbb, pixels.

    Returns
    -------
    ChaosMeasures
    """
    sweep = read_complete_sweep(path)
    return measure_map(
        sweep.outcome, sweep.sides, box_size, x_step=_cell_width(sweep.x), y_step=_cell_width(sweep.y)
    )


def _json_float(value):
    """A float for JSON: NaN becomes None (JSON has no NaN)."""
    return None if value is None or not math.isfinite(value) else float(value)


# --- maps with known answers (tests, docs/chaos.md) -------------------------------------


def straight_boundary_map(shape, slope, offset) -> np.ndarray:
    """int8 map: 1 above the line y = slope x + offset (pixel units, through pixel centres), else 0."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (rows + 0.5 > slope * (cols + 0.5) + offset).astype(np.int8)


def checkerboard_map(shape, block, shift=0) -> np.ndarray:
    """int8 checkerboard of ``block`` x ``block`` pixel squares, its edges ``shift`` pixels in."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (((rows + block - shift) // block + (cols + block - shift) // block) % 2).astype(np.int8)


def cantor_map(levels, rows) -> np.ndarray:
    """A middle-thirds Cantor boundary times a line: ``rows`` x 3^levels pixels.

    Every interval removed by the construction is a basin of its own, and so is every pixel
    never removed (a point of the set at this resolution), so the boundary is exactly the
    Cantor set, of dimension ln 2 / ln 3: alpha = 1 - ln 2 / ln 3 along the columns.
    """
    pixel = np.arange(3**levels)
    basin = 3**levels + pixel
    removed = np.zeros(pixel.shape, dtype=bool)
    for stage in range(levels):
        width = 3 ** (levels - 1 - stage)
        middle = ((pixel // width) % 3 == 1) & ~removed
        basin[middle] = (pixel[middle] // width) * width  # first pixel of the removed interval
        removed |= middle
    return np.tile(basin, (rows, 1))


def weierstrass_map(pixels, a, b, terms=20) -> np.ndarray:
    """int8 map, 1 above the graph of W(x) = sum_k a^k cos(2 pi b^k x + k), x in [0, 1].

    The graph has box-counting dimension 2 + ln a / ln b, so alpha = -ln a / ln b; the
    pixels resolve only about log_b(pixels) octaves of W.
    """
    x = (np.arange(pixels) + 0.5) / pixels
    w = sum(a**k * np.cos(2 * np.pi * b**k * x + k) for k in range(terms))
    y = (np.arange(pixels) + 0.5) / pixels * 4 - 2  # W stays within +-2 for a <= 1/2
    return (y[:, np.newaxis] > w[np.newaxis, :]).astype(np.int8)


def random_map_entropy(box_pixels, outcomes) -> float:
    """Expected Sb (= Sbb) of a map of independent, equally likely outcomes.

    The exact mean entropy of the shares of ``box_pixels`` uniform draws among ``outcomes``
    (a sum over the multinomial distribution); it is below ln(outcomes) by about
    (outcomes - 1) / (2 box_pixels).
    """

    def compositions(total, parts):
        if parts == 1:
            yield (total,)
            return
        for first in range(total + 1):
            for rest in compositions(total - first, parts - 1):
                yield (first, *rest)

    mean = 0.0
    for counts in compositions(box_pixels, outcomes):
        ways = math.factorial(box_pixels)
        for count in counts:
            ways //= math.factorial(count)
        entropy = -sum(c / box_pixels * math.log(c / box_pixels) for c in counts if c)
        mean += ways * entropy / outcomes**box_pixels
    return mean


# --- control maps -------------------------------------------------------------------------


def parse_sigma(text: str) -> tuple[str, float]:
    """``"PARAM=STD"`` (the ``--sigma`` option) -> (param, standard deviation in SI units).

    Raises
    ------
    DiceSweepError
        If PARAM is not an initial value or STD is not a number in [0, MAX_SIGMA].
    """
    param, _, value = text.partition("=")
    param = param.strip()
    try:
        sigma = float(value)
    except ValueError:
        sigma = math.nan
    if param not in GRID_PARAMS or not 0 <= sigma <= MAX_SIGMA:
        raise DiceSweepError(
            f"--sigma {text!r}: expected PARAM=STD with PARAM one of {', '.join(GRID_PARAMS)} "
            f"and 0 <= STD <= {MAX_SIGMA:g} in its SI unit, e.g. --sigma y0=0.002"
        )
    return param, sigma


@dataclasses.dataclass(frozen=True)
class ControlMap:
    """The probability of every outcome for a thrower aiming at each point of a grid.

    Attributes
    ----------
    method : str
        ``"blur"`` (Gaussian blur of the outcome indicators of the map) or ``"monte_carlo"``.
    sigmas : dict of str to float
        Standard deviation of each scattered initial value, SI units.
    sides : int
    x_param, y_param : str
        Parameters of the columns and rows.
    x_values, y_values : numpy.ndarray
        Aimed values of the columns and rows (cell centres of the map, or a subset of them).
    probability : numpy.ndarray
        float (n + 1, ny, nx): row k is the probability of side k, row n that of no answer.
    samples : int
        Monte Carlo rolls per point (0 for the blur).
    weight_inside : numpy.ndarray or None
        Blur only: float (ny, nx), share of the Gaussian's weight that falls on the map. Near
        the edges the blur uses only that part (renormalised), so the probabilities there are
        those of a thrower whose scatter is cut at the map's edges.
    """

    method: str
    sigmas: dict[str, float]
    sides: int
    x_param: str
    y_param: str
    x_values: np.ndarray
    y_values: np.ndarray
    probability: np.ndarray
    samples: int = 0
    weight_inside: np.ndarray | None = None

    @property
    def most_likely(self) -> np.ndarray:
        """int (ny, nx): most likely side, -1 where no answer is the most likely."""
        best = np.argmax(self.probability, axis=0)
        return np.where(best == self.sides, UNDECIDED, best)

    @property
    def p_max(self) -> np.ndarray:
        """float (ny, nx): probability of the most likely outcome."""
        return self.probability.max(axis=0)

    @property
    def entropy(self) -> np.ndarray:
        """float (ny, nx): outcome entropy -sum_k p_k ln p_k, nats (ln n for a fair die)."""
        p = self.probability
        return -np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0), axis=0)

    def summary(self) -> dict:
        """Plane-averaged numbers, JSON-ready."""
        p_max, entropy = self.p_max, self.entropy
        return {
            "method": self.method,
            "sigmas": dict(self.sigmas),
            "samples_per_point": self.samples,
            "shape": list(p_max.shape),
            "mean_p_max": float(p_max.mean()),
            "median_p_max": float(np.median(p_max)),
            f"share_p_max_at_least_{CONTROLLED_PROBABILITY:g}": float((p_max >= CONTROLLED_PROBABILITY).mean()),
            "mean_entropy_nats": float(entropy.mean()),
            "max_entropy_nats": float(entropy.max()),
            "fair_die_entropy_nats": math.log(self.sides),
        }

    def describe(self) -> str:
        """A few lines for the user."""
        s = self.summary()
        how = "Gaussian blur of the map" if self.method == "blur" else f"Monte Carlo, {self.samples} rolls per point"
        sigmas = ", ".join(f"{k} {v:g} {PARAM_UNITS[k]}" for k, v in self.sigmas.items())
        return (
            f"control map {s['shape'][0]} x {s['shape'][1]} by {how}; sigma: {sigmas}\n"
            f"most likely side has probability {s['mean_p_max']:.3f} on average (median {s['median_p_max']:.3f}); "
            f"share of points with p >= {CONTROLLED_PROBABILITY:g}: "
            f"{s[f'share_p_max_at_least_{CONTROLLED_PROBABILITY:g}']:.3f}; "
            f"mean outcome entropy {s['mean_entropy_nats']:.3f} nats (fair die: ln {self.sides} = {math.log(self.sides):.3f})"
        )

    def to_npz(self, path) -> None:
        """Save the maps (probability, most_likely, p_max, entropy, axes) as a NumPy .npz."""
        np.savez_compressed(
            path,
            probability=self.probability,
            most_likely=self.most_likely,
            p_max=self.p_max,
            entropy=self.entropy,
            x_values=self.x_values,
            y_values=self.y_values,
            x_param=self.x_param,
            y_param=self.y_param,
            method=self.method,
            sigmas=np.array([f"{k}={v!r}" for k, v in self.sigmas.items()]),
        )


def _smooth_axis(values, sigma_pixels, axis):
    """Gaussian-weighted sums of ``values`` along ``axis`` (zero outside the map)."""
    if sigma_pixels == 0:
        return values
    # offsets beyond the map add only zeros: a kernel wider than the map is cut to it
    reach = max(values.shape[axis] - 1, 1)
    half = reach if BLUR_TRUNCATE * sigma_pixels >= reach else int(math.ceil(BLUR_TRUNCATE * sigma_pixels))
    offsets = np.arange(-half, half + 1)
    weights = np.exp(-0.5 * (offsets / sigma_pixels) ** 2)
    weights /= weights.sum()
    moved = np.moveaxis(values, axis, -1)
    padded = np.zeros((*moved.shape[:-1], moved.shape[-1] + 2 * half))
    padded[..., half:-half] = moved
    smoothed = np.zeros(moved.shape)
    for weight, offset in zip(weights, offsets):
        smoothed += weight * padded[..., half + offset : half + offset + moved.shape[-1]]
    return np.moveaxis(smoothed, -1, axis)


def blur_probabilities(outcome, sides, sigma_pixels) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian blur of the outcome indicators of a map, renormalised inside the map.

    Parameters
    ----------
    outcome : array_like of int, shape (ny, nx)
    sides : int
    sigma_pixels : tuple of float
        (along y, along x) standard deviations in cells; 0 = no scatter along that axis.

    Returns
    -------
    probability : numpy.ndarray
        float (n + 1, ny, nx); row n is the undecided outcome.
    weight_inside : numpy.ndarray
        float (ny, nx): share of each point's Gaussian weight that lies on the map.
    """
    outcome = np.asarray(outcome)
    codes = np.where(outcome == UNDECIDED, sides, outcome)
    indicators = (codes[np.newaxis] == np.arange(sides + 1)[:, np.newaxis, np.newaxis]).astype(float)
    sigma_y, sigma_x = sigma_pixels
    weight = _smooth_axis(_smooth_axis(np.ones((1, *outcome.shape)), sigma_y, 1), sigma_x, 2)
    blurred = _smooth_axis(_smooth_axis(indicators, sigma_y, 1), sigma_x, 2)
    return blurred / weight, weight[0]


def choose_method(sweep, sigmas) -> str:
    """``"blur"`` if the map resolves every scatter, else ``"monte_carlo"``.

    The blur needs every scattered value to be an axis of the map, with sigma either 0 or at
    least ``BLUR_MIN_PIXELS`` cells.
    """
    steps = {sweep.x.param: _cell_width(sweep.x), sweep.y.param: _cell_width(sweep.y)}
    for param, sigma in sigmas.items():
        if sigma > 0 and (param not in steps or sigma < BLUR_MIN_PIXELS * steps[param]):
            return "monte_carlo"
    return "blur"


def _blur_control(sweep, sigmas) -> ControlMap:
    sigma_pixels = tuple(sigmas.get(axis.param, 0.0) / _cell_width(axis) for axis in (sweep.y, sweep.x))
    probability, weight = blur_probabilities(sweep.outcome, sweep.sides, sigma_pixels)
    return ControlMap(
        "blur", dict(sigmas), sweep.sides, sweep.x.param, sweep.y.param,
        sweep.x.values, sweep.y.values, probability, 0, weight,
    )


def monte_carlo_indices(length: int, max_points: int) -> np.ndarray:
    """Indices of at most ``max_points`` evenly spread cells of an axis of ``length`` cells.

    Every ``stride``-th cell, starting half a stride in, so that the points sit in the
    middle of the blocks they stand for.
    """
    stride = max(1, math.ceil(length / max_points))
    return np.arange(stride // 2, length, stride)


def _start_clear(cfg, states) -> np.ndarray:
    """bool (N,): starts with no corner inside the table or a wall (as the config check)."""
    from dice_sweep.geometry import DOWN, support

    sides, radius = cfg.die.sides, cfg.die.circumradius
    x, y, phi = states[:, 0], states[:, 1], states[:, 2]
    clear = y >= support(sides, radius, phi, DOWN)
    if cfg.walls.separation is not None:
        half = 0.5 * cfg.walls.separation
        clear &= (x + support(sides, radius, phi, 0.0) <= half) & (x - support(sides, radius, phi, np.pi) >= -half)
    return clear


def scattered_starts(cfg, centres, sigmas, samples, rng) -> np.ndarray:
    """``samples`` Gaussian starts around each of ``centres``, none inside a surface.

    A draw that puts a corner inside the table or a wall is drawn again (a truncated
    Gaussian: nobody throws a die from inside the table); after ``START_DRAWS`` tries the
    aimed start is used.

    Parameters
    ----------
    cfg : dice_sweep.config.Config
    centres : numpy.ndarray
        float (P, 6): aimed starts, columns ``STATE_COLUMNS``.
    sigmas : dict of str to float
        Standard deviation per initial value, SI units.
    samples : int
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray
        float (P * samples, 6), the samples of point p in rows p * samples ... (p + 1) * samples - 1.
    """
    from dice_sweep.physics.layout import STATE_COLUMNS

    aimed = np.repeat(centres, samples, axis=0)
    scale = np.zeros(len(STATE_COLUMNS))
    for param, sigma in sigmas.items():
        scale[STATE_COLUMNS.index(param)] = sigma
    starts = aimed.copy()
    redraw = np.ones(len(starts), dtype=bool)
    for _ in range(START_DRAWS):
        starts[redraw] = aimed[redraw] + rng.standard_normal((int(redraw.sum()), len(scale))) * scale
        redraw = ~_start_clear(cfg, starts)
        if not redraw.any():
            break
    starts[redraw] = aimed[redraw]
    return starts


def monte_carlo_probabilities(cfg, xs, ys, sigmas, samples, *, seed=0, workers=1) -> np.ndarray:
    """Share of ``samples`` scattered rolls ending on each outcome, at every (y, x) point.

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        Config with a grid (its swept parameters name the axes of xs and ys).
    xs, ys : array_like
        Aimed values of the grid's x and y parameters.
    sigmas : dict of str to float
        Standard deviations, SI units.
    samples : int
        Rolls per point.
    seed : int
        Seed of the random draws (the result is reproducible).
    workers : int
        Worker processes for the rolls.

    Returns
    -------
    numpy.ndarray
        float (n + 1, len(ys), len(xs)); row n is the undecided outcome.
    """
    from dice_sweep.refine import roll_states
    from dice_sweep.sweep import SweepJob, initial_states

    sides = cfg.die.sides
    starts = scattered_starts(cfg, initial_states(cfg, xs, ys), sigmas, samples, np.random.default_rng(seed))
    outcome = roll_states(SweepJob.from_config(cfg), starts, workers)[0].astype(np.int64)
    codes = np.where(outcome == UNDECIDED, sides, outcome).reshape(len(ys) * len(xs), samples)
    counts = np.stack([(codes == k).sum(axis=1) for k in range(sides + 1)])
    return (counts / samples).reshape(sides + 1, len(ys), len(xs))


def _monte_carlo_control(sweep, sigmas, samples, max_points, seed, workers) -> ControlMap:
    from dice_sweep.config import parse_config

    cfg = parse_config(sweep.config_toml, source=f"{sweep.path}: config_toml")
    from dice_sweep.sweep import worker_count

    xs = sweep.x.values[monte_carlo_indices(len(sweep.x.values), max_points)]
    ys = sweep.y.values[monte_carlo_indices(len(sweep.y.values), max_points)]
    if len(xs) * len(ys) * samples > MAX_MC_ROLLS:
        raise DiceSweepError(f"--samples {samples} at {len(ys)} x {len(xs)} points: {len(xs) * len(ys) * samples} rolls "
                             f"(allowed: --samples x points at most {MAX_MC_ROLLS}; lower --samples or --points)")
    workers = worker_count(workers)
    probability = monte_carlo_probabilities(cfg, xs, ys, sigmas, samples, seed=seed, workers=workers)
    return ControlMap(
        "monte_carlo", dict(sigmas), sweep.sides, sweep.x.param, sweep.y.param, xs, ys, probability, samples
    )


METHODS = ("auto", "blur", "monte_carlo")


def control_map(
    sweep, sigmas, *, method="auto", samples=DEFAULT_SAMPLES, max_points=DEFAULT_MC_POINTS, seed=0, workers=1
) -> ControlMap:
    """Outcome probabilities for a thrower with Gaussian scatter ``sigmas``, over a sweep's plane.

    Parameters
    ----------
    sweep : dice_sweep.storage.SweepData
        A complete sweep (its map for the blur, its config for Monte Carlo).
    sigmas : dict of str to float
        Standard deviation of each scattered initial value, SI units.
    method : {"auto", "blur", "monte_carlo"}
        ``auto`` takes :func:`choose_method`. ``blur`` is refused where it does not apply.
    samples : int
        Monte Carlo rolls per point.
    max_points : int
        Monte Carlo points per axis, at most (a subset of the map's cell centres).
    seed : int
        Seed of the Monte Carlo draws.
    workers : int, optional
        Worker processes for the Monte Carlo rolls; None: all cores this process may use.

    Returns
    -------
    ControlMap

    Raises
    ------
    DiceSweepError
        On no sigma, an unknown method, or a blur the map cannot resolve.
    """
    if not sigmas:
        raise DiceSweepError("control: give at least one --sigma PARAM=STD, e.g. --sigma y0=0.002")
    if method not in METHODS:
        raise DiceSweepError(f"--method {method!r}: expected one of {', '.join(METHODS)}")
    if samples < 1 or max_points < 1:
        raise DiceSweepError(f"--samples {samples}, --points {max_points}: need at least 1")
    if seed < 0:
        raise DiceSweepError(f"--seed: {seed} is outside the allowed range [0, inf) (whole numbers)")
    best = choose_method(sweep, sigmas)
    if method == "blur" and best != "blur":
        raise DiceSweepError(
            f"--method blur: every --sigma must be 0 or at least {BLUR_MIN_PIXELS:g} cells of an axis of the map "
            f"({sweep.x.param}, {sweep.y.param}); use --method monte_carlo"
        )
    if (best if method == "auto" else method) == "blur":
        return _blur_control(sweep, sigmas)
    return _monte_carlo_control(sweep, sigmas, samples, max_points, seed, workers)


def control_file(path, sigmas, **options) -> ControlMap:
    """:func:`control_map` of a complete sweep file; ``options`` as there."""
    return control_map(read_complete_sweep(path), sigmas, **options)


@dataclasses.dataclass(frozen=True)
class ControlAgreement:
    """How well a blurred control map agrees with Monte Carlo at the Monte Carlo points.

    Attributes
    ----------
    points : int
        Points compared: Monte Carlo points where the blur's Gaussian lies on the map
        (weight inside at least 0.999), so that both see the same scatter.
    mean_abs_difference : float
        Mean over points and outcomes of |p_blur - p_mc|.
    max_abs_difference : float
    mean_mc_standard_error : float
        Mean binomial standard error sqrt(p (1 - p) / samples) of the Monte Carlo shares.
    share_within_3_se : float
        Share of (point, outcome) pairs with |p_blur - p_mc| <= 3 standard errors (the
        standard error floored at 1 / samples).
    same_most_likely : float
        Share of points where both give the same most likely side.
    median_gap_where_different : float
        Where they do not: the median gap between the blur's two largest probabilities (a
        small gap means a near tie that Monte Carlo noise can flip). NaN if they always agree.
    """

    points: int
    mean_abs_difference: float
    max_abs_difference: float
    mean_mc_standard_error: float
    share_within_3_se: float
    same_most_likely: float
    median_gap_where_different: float

    def to_dict(self) -> dict:
        """JSON-ready."""
        return dataclasses.asdict(self)


def compare_control(blurred: ControlMap, monte_carlo: ControlMap, x_index, y_index) -> ControlAgreement:
    """Compare a blurred control map with a Monte Carlo one at the Monte Carlo points.

    Parameters
    ----------
    blurred : ControlMap
        ``method == "blur"``, on the whole map.
    monte_carlo : ControlMap
        On the cells ``x_index`` x ``y_index`` of the same map.
    x_index, y_index : array_like of int
        Cells of the map the Monte Carlo points sit at (:func:`monte_carlo_indices`).

    Returns
    -------
    ControlAgreement
    """
    rows, cols = np.ix_(np.asarray(y_index), np.asarray(x_index))
    inside = blurred.weight_inside[rows, cols] >= 0.999
    p_blur = blurred.probability[:, rows, cols][:, inside]
    p_mc = monte_carlo.probability[:, inside]
    difference = np.abs(p_blur - p_mc)
    standard_error = np.sqrt(p_mc * (1 - p_mc) / monte_carlo.samples)
    floor = np.maximum(standard_error, 1.0 / monte_carlo.samples)
    different = p_blur.argmax(axis=0) != p_mc.argmax(axis=0)
    top_two = np.sort(p_blur, axis=0)[-2:]
    gaps = (top_two[1] - top_two[0])[different]
    return ControlAgreement(
        points=int(inside.sum()),
        mean_abs_difference=float(difference.mean()),
        max_abs_difference=float(difference.max()),
        mean_mc_standard_error=float(standard_error.mean()),
        share_within_3_se=float((difference <= 3 * floor).mean()),
        same_most_likely=float(1.0 - different.mean()),
        median_gap_where_different=float(np.median(gaps)) if gaps.size else math.nan,
    )


# --- files: what the measure and control commands write ------------------------------------


def write_json(path, data) -> pathlib.Path:
    """Write ``data`` as indented JSON; return the path."""
    path = pathlib.Path(path)
    path.write_text(json.dumps(data, indent=2) + "\n")
    return path


def _png_folder(png_dir) -> pathlib.Path:
    check_outputs(("--png", png_dir, FOLDER))
    folder = pathlib.Path(png_dir)
    folder.mkdir(exist_ok=True)
    return folder


def _axis_labels(sweep) -> tuple[str, str]:
    from dice_sweep.plotting import axis_label

    return axis_label(sweep.x.param, sweep.x.unit), axis_label(sweep.y.param, sweep.y.unit)


def box_entropy_panel(sweep, entropy: BasinEntropy, title=None) -> dict:
    """Keyword arguments of :func:`dice_sweep.plotting.draw_scalar_map` for a map of box entropies.

    Parameters
    ----------
    sweep : dice_sweep.storage.SweepData
        The sweep the entropies were measured on (axes, units, sides).
    entropy : BasinEntropy
    title : str, optional
        Default: box size, Sb and Sbb.
    """
    rows, cols = entropy.used_shape
    x_label, y_label = _axis_labels(sweep)
    extent = (sweep.x.lo, sweep.x.lo + cols * _cell_width(sweep.x), sweep.y.lo, sweep.y.lo + rows * _cell_width(sweep.y))
    title = title or f"box entropy, {entropy.box_size} x {entropy.box_size} pixels: Sb = {entropy.sb:.3f}, Sbb = {entropy.sbb:.3f}"
    return dict(values=entropy.box_entropy, x_values=None, y_values=None, x_label=x_label, y_label=y_label,
                title=title, label="nats", vmin=0.0, vmax=math.log(sweep.sides + 1), cmap="magma", extent=extent)


def measure_pictures(sweep, measures: ChaosMeasures, png_dir) -> list[pathlib.Path]:
    """Draw f(eps) with its fit and the map of box entropies into ``png_dir``.

    Returns
    -------
    list of pathlib.Path
        ``uncertainty.png`` and ``box_entropy.png``.
    """
    from dice_sweep.plotting import plot_scalar_maps, plot_uncertainty_curves

    folder = _png_folder(png_dir)
    return [
        plot_uncertainty_curves([measures.uncertainty], [pathlib.Path(sweep.path).name], folder / "uncertainty.png"),
        plot_scalar_maps([box_entropy_panel(sweep, measures.entropy)], folder / "box_entropy.png"),
    ]


def run_measure(path, *, box_size=DEFAULT_BOX_SIZE, json_path=None, png_dir=None) -> ChaosMeasures:
    """The ``measure`` command: measure a sweep file, optionally write JSON and pictures.

    Parameters
    ----------
    path : str or os.PathLike
        Complete sweep file.
    box_size : int
        Box side for Sb and Sbb, pixels.
    json_path : str or os.PathLike, optional
        Write every number (:meth:`ChaosMeasures.to_dict`) here.
    png_dir : str or os.PathLike, optional
        Folder (created if missing) for ``uncertainty.png`` and ``box_entropy.png``.

    Returns
    -------
    ChaosMeasures
    """
    check_outputs(("--json", json_path, JSON), ("--png", png_dir, FOLDER))
    sweep = read_complete_sweep(path)
    measures = measure_map(sweep.outcome, sweep.sides, box_size, x_step=_cell_width(sweep.x), y_step=_cell_width(sweep.y))
    if json_path:
        write_json(json_path, {"file": str(path), **measures.to_dict()})
    if png_dir:
        measure_pictures(sweep, measures, png_dir)
    return measures


def run_control(path, sigmas, *, json_path=None, png_dir=None, npz_path=None, **options) -> ControlMap:
    """The ``control`` command: a control map of a sweep file, optionally JSON, pictures, arrays.

    Parameters
    ----------
    path : str or os.PathLike
        Complete sweep file.
    sigmas : dict of str to float
        Standard deviations of the scattered initial values, SI units.
    json_path : str or os.PathLike, optional
        Write :meth:`ControlMap.summary` here.
    png_dir : str or os.PathLike, optional
        Folder (created if missing) for ``control.png``.
    npz_path : str or os.PathLike, optional
        Save the maps here (:meth:`ControlMap.to_npz`).
    **options
        As :func:`control_map` (method, samples, max_points, seed, workers).

    Returns
    -------
    ControlMap
    """
    from dice_sweep.plotting import plot_control_map

    check_outputs(("--json", json_path, JSON), ("--png", png_dir, FOLDER), ("--output", npz_path, NPZ))
    sweep = read_complete_sweep(path)
    control = control_map(sweep, sigmas, **options)
    if json_path:
        write_json(json_path, {"file": str(path), **control.summary()})
    if png_dir:
        plot_control_map(control, _png_folder(png_dir) / "control.png", *_axis_labels(sweep))
    if npz_path:
        control.to_npz(npz_path)
    return control
