"""Control maps: a thrower whose initial values scatter with standard deviations sigma gets
each side with a probability that depends on the aimed point. It is the Gaussian blur of the
side's indicator on a fine map, or, where the map is too coarse for that (or a scattered
value is not an axis of the map), the share of Monte Carlo rolls that land on the side.

The Monte Carlo rolls are a strategy over the mapper (:func:`dice_sweep.mapper.roll_states`,
on the one worker pool).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from dice_sweep.chaos.measures import UNDECIDED, shannon_entropy
from dice_sweep.config import GRID_PARAMS, PARAM_UNITS, parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import workers_or_default
from dice_sweep.outputs import written
from dice_sweep.geometry import clear_of_surfaces
from dice_sweep.physics.layout import STATE_COLUMNS
from dice_sweep.mapper import Mapper, draw_streams, initial_states, roll_states

BLUR_MIN_PIXELS = 2.0  # the blur needs sigma at least this many cells wide on a blurred axis
BLUR_TRUNCATE = 4.0  # the Gaussian kernel is cut at this many sigma
DEFAULT_SAMPLES = 256  # Monte Carlo rolls per point
DEFAULT_MC_POINTS = 64  # Monte Carlo points per axis, at most
CONTROLLED_PROBABILITY = 0.9  # a point where one side has at least this probability is "controlled"
START_DRAWS = 100  # redraws of a Monte Carlo start that put a corner inside a surface
MAX_SIGMA = 1e300  # --sigma: a larger one overflows the Monte Carlo draws to inf
MAX_MC_ROLLS = 10_000_000  # Monte Carlo rolls of one control map: their starts are held in memory (~200 B each)


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
        return shannon_entropy(self.probability)

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
        with written(path) as temporary:  # whole or nothing
            np.savez_compressed(
                temporary,
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
    steps = {sweep.x.param: sweep.x.cell_width, sweep.y.param: sweep.y.cell_width}
    for param, sigma in sigmas.items():
        if sigma > 0 and (param not in steps or sigma < BLUR_MIN_PIXELS * steps[param]):
            return "monte_carlo"
    return "blur"


def _blur_control(sweep, sigmas) -> ControlMap:
    sigma_pixels = tuple(sigmas.get(axis.param, 0.0) / axis.cell_width for axis in (sweep.y, sweep.x))
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
    aimed = np.repeat(centres, samples, axis=0)
    scale = np.zeros(len(STATE_COLUMNS))
    for param, sigma in sigmas.items():
        scale[STATE_COLUMNS.index(param)] = sigma
    starts = aimed.copy()
    redraw = np.ones(len(starts), dtype=bool)
    for _ in range(START_DRAWS):
        starts[redraw] = aimed[redraw] + rng.standard_normal((int(redraw.sum()), len(scale))) * scale
        redraw = ~clear_of_surfaces(cfg.die.sides, cfg.die.circumradius, cfg.walls.separation, starts, cfg.effects.corner_radius)
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
    sides = cfg.die.sides
    starts = scattered_starts(cfg, initial_states(cfg, xs, ys), sigmas, samples, np.random.default_rng(seed))
    # with [scatter], roll k of point i on its own stream (i, k): as a probability sweep's pixel
    streams = draw_streams(np.arange(len(xs) * len(ys)), samples) if cfg.scatter.on else None
    outcome = roll_states(Mapper.from_config(cfg), starts, workers, streams=streams)[0].astype(np.int64)
    codes = np.where(outcome == UNDECIDED, sides, outcome).reshape(len(ys) * len(xs), samples)
    counts = np.stack([(codes == k).sum(axis=1) for k in range(sides + 1)])
    return (counts / samples).reshape(sides + 1, len(ys), len(xs))


def _monte_carlo_control(sweep, sigmas, samples, max_points, seed, workers) -> ControlMap:
    cfg = parse_config(sweep.config_toml, source=f"{sweep.path}: config_toml")
    xs = sweep.x.values[monte_carlo_indices(len(sweep.x.values), max_points)]
    ys = sweep.y.values[monte_carlo_indices(len(sweep.y.values), max_points)]
    if len(xs) * len(ys) * samples > MAX_MC_ROLLS:
        raise DiceSweepError(f"--samples {samples} at {len(ys)} x {len(xs)} points: {len(xs) * len(ys) * samples} rolls "
                             f"(allowed: --samples x points at most {MAX_MC_ROLLS}; lower --samples or --points)")
    workers = workers_or_default(workers)
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
