"""Side probabilities for tracked drops, from what was seen before they landed (issue 18).

A deterministic forecast of a chaotic system is the wrong instrument: the right one is a
probability for each side, from everything known and its uncertainty. For each track and each
forecast point K (the K-th free flight the tracking resolves; K = 0 is the release):

1. **The state seen.** The frames of flight K alone (nothing after its end, so nothing after
   the next impact) are fitted by the model's own flight (the kernel, with the fitted
   parameters: flight and measurement effects included) for the state (x, y, phi, vx, vy,
   omega) at the flight's first frame. Its covariance is the inverse of the Gauss-Newton
   normal matrix of that fit with the tracking noise the loop estimated (sigma of x, y, phi),
   multiplied by the flight's own reduced chi-square when that is above 1 (the Birge ratio:
   a flight the model misfits, or a tracker whose errors last several frames, says less than
   white noise of that sigma would).
2. **The model's parameters.** Draws of the loop's one-step bootstrap over tracks
   (``bootstrap_draws`` of the fit JSON), or, for a JSON without them, independent Gaussians
   whose 95 % intervals are the JSON's ``ci95`` (said in the output).
3. **The ensemble.** ``members`` starts: ``param_draws`` parameter draws, each with the same
   number of state draws per track from the state's Gaussian. A start with a corner inside the
   table (or a wall) is drawn again (the flight was seen above it). Every member is rolled to
   rest by the sweep kernel (``roll_batch``); the side counts, with half a member added to
   every side (the Jeffreys estimate: no side gets probability 0), give the probabilities.
4. **Scores** on the tracks' resting sides (the side below the centre of a die at rest in its
   last frames; tracks not at rest are left out): mean log score (natural log of the
   probability given to the side that happened), Brier score (sum over sides of the squared
   difference), beside the uniform forecast 1/n and the deterministic one (the best-fit state
   and parameters rolled once), each with a 95 % interval from a bootstrap over tracks; the
   reliability diagram; and a calibration test: under the hypothesis that each side happens
   with the forecast's probability, the mean log score and Brier score have known means and
   variances, whose z-scores the output gives.

What is not in the ensemble: the model's own error (the fitted model misses real flights and
impacts by far more than the tracking noise, docs/measured.md), the choice between optima of
the fit, correlations between a flight's state and flight parameters (the state is fitted at
the best parameters), and noise that is not white. docs/forecast.md says what that does to the
scores on real drops.

Plain numbers and arrays out; no plotting (dice_sweep.plotting draws them), no files (the app
layer reads the fit JSON text and writes the outputs).
"""

import dataclasses
import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.config import MAX_SCATTER
from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import ordered_map
from dice_sweep.geometry import clear_of_surfaces, side_below
from dice_sweep.measured import fit as shooting
from dice_sweep.measured.blocks import segment_products, segment_sums
from dice_sweep.measured.fit import kernel_config
from dice_sweep.measured.impacts import rest_pose
from dice_sweep.mapper import Mapper
from dice_sweep.measured.stats import Z95
from dice_sweep.physics import STATE_COLUMNS

MIN_MEMBERS = 1000  # the command refuses smaller ensembles (the library takes any >= 1)
DEFAULT_MEMBERS = 2000
PARAM_DRAWS = 50  # parameter draws per ensemble; each gets members / PARAM_DRAWS state draws
SMOOTHING = 0.5  # members added to every side's count (Jeffreys): no probability is 0
BOOTSTRAP = 2000  # resamples of the tracks for every interval
RELIABILITY_BINS = 10
MIN_BOUNCE_TRACKS = 5  # a forecast point with fewer scored tracks is left out of by_bounce
REDRAWS = 20  # times a start inside the table is drawn again before the member is dropped
FLIGHT_TIME_MARGIN = 1e-3  # s past a flight's last frame the fit's kernel runs
# members per selection track: they only fit the blend's weight (a comparison row), and 2000 of them
# were 70 % of the forecast's time on the real drops
SELECTION_MEMBERS = 250
STREAMS_PER_BOUNCE = 10**6  # random-stream draw indices per forecast point (above any parameter draw count)


# --- the fit a forecast samples --------------------------------------------------------------


@dataclass(frozen=True)
class FitSource:
    """What a forecast needs from the JSON of ``fit`` or ``diagnose``."""

    path: str
    kind: str  # "fit" or "diagnose"
    effects: tuple  # effects the fit added to the config's declared model
    params: dict  # name -> best value (registry units)
    names: tuple  # fitted parameters, in the order of the draws' columns
    draws: object  # (D, p) bootstrap draws, or None
    sd: object  # (p,) Gaussian sds from ci95 when there are no draws, else None
    parameter_note: str
    confirm_fraction: float
    seed: int
    data_path: object  # the data file the fit was made on, if the JSON says
    angle_reading: object
    # the stochastic impact law written with the fit ({"corner": s, "flat": s, "corner_floor": f, ..., "power": p},
    # dice_sweep.measured.scatter), or None: the ensemble's impacts follow the fitted law exactly
    scatter: object = None
    scatter_scale: object = None  # the factor already applied to ``scatter`` (fit_scatter_scale's dict), or None

    def spec(self, cfg):
        return shooting.ModelSpec.of(cfg, self.effects)


def _fit_error(path, message):
    return DiceSweepError(f"--fit: {path}: {message} (allowed: the JSON written by dice-sweep fit --json or dice-sweep diagnose --json "
                          "for this config's die)")


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def parse_fit(data, path, cfg, confirm_fraction, seed):
    """A :class:`FitSource` from the decoded JSON of ``fit`` or ``diagnose`` (``path`` names it
    in errors; ``confirm_fraction`` and ``seed``: the split when the JSON does not say). One-line
    errors for a JSON that is not a fit, or a fit of another die or model."""
    if not isinstance(data, dict):
        raise _fit_error(path, "not a JSON object")
    if isinstance(data.get("held_out_model"), dict) and "effects_added" in data:
        # a cross-fitted diagnose (issue 30): its named model saw every track; fold 0's model did
        # not see the half its split holds out
        data = {**data, **{key: data["held_out_model"][key] for key in ("bootstrap_draws", "split") if key in data["held_out_model"]}}
        kind, params, effects = "diagnose (held-out fold)", data["held_out_model"].get("params"), data["held_out_model"].get("effects")
    elif isinstance(data.get("after"), dict) and "effects_added" in data:
        kind, params, effects = "diagnose", data["after"].get("params"), data["after"].get("effects")
    elif "params" in data and "effects" in data:
        kind, params, effects = "fit", data["params"], data["effects"]
    else:
        missing = [key for key in ("params", "effects") if key not in data]
        raise _fit_error(path, f"no key {missing[0]!r}: not a fit")
    if not isinstance(params, dict) or not params or not isinstance(effects, list):
        raise _fit_error(path, "its 'params' or 'effects' is empty or of the wrong type")
    die = data.get("die")
    if isinstance(die, dict):
        sides, radius = die.get("sides"), die.get("circumradius")
        if sides != cfg.die.sides or not _number(radius) or abs(radius - cfg.die.circumradius) > 1e-9 * cfg.die.circumradius:
            raise _fit_error(path, f"a fit of a die with n = {sides}, R = {radius} m, not the config's n = {cfg.die.sides}, "
                                   f"R = {cfg.die.circumradius:g} m")
    unknown = [name for name in effects if name not in registry.names()]
    if unknown:
        raise _fit_error(path, f"unknown effect {unknown[0]!r}")
    declared = registry.declared_effects(cfg)
    extra = tuple(name for name in effects if name not in declared)
    spec = shooting.ModelSpec.of(cfg, extra)
    names = tuple(spec.param_names())
    if set(params) != set(names):
        raise _fit_error(path, f"its parameters ({', '.join(sorted(params))}) are not those of the config's model with its effects "
                               f"({', '.join(names)}): a fit of another model")
    values = {}
    for name in names:
        entry = params[name]
        value = entry.get("value") if isinstance(entry, dict) else None
        if not _number(value):
            raise _fit_error(path, f"params.{name}.value is not a number")
        values[name] = float(value)
    draws, sd, note = _parameter_draws(data, params, names, path)
    split = data.get("split") if isinstance(data.get("split"), dict) else {}
    fraction = split.get("confirm_fraction", confirm_fraction)
    split_seed = split.get("seed", seed)
    data_path = data.get("data", {}).get("path") if isinstance(data.get("data"), dict) else None
    return FitSource(str(path), kind, extra, values, names, draws, sd, note, float(fraction), int(split_seed), data_path,
                     data.get("angle_reading"), _scatter_of(data, path), _scale_of(data))


def _scatter_of(data, path):
    """{"corner": s, "flat": s, "corner_floor": f, "flat_floor": f, "power": p, "tail_share": w,
    "tail_factor": k, "spin": c} from a fit JSON's ``scatter`` (a JSON from before the power or
    the shape existed: their null values, the law it was estimated with),
    the spreads and floors times the JSON's ``scatter_scale`` when it has one
    (:func:`fit_scatter_scale`); None without one."""
    record = data.get("scatter")
    if record is None:
        return None
    spreads = {}
    for kind in registry.SCATTER_KINDS:
        entry = record.get(kind) if isinstance(record, dict) else None
        for key, name in zip(("value", "floor"), registry.scatter_spread_keys(kind)):
            value = entry.get(key, 0.0 if key == "floor" else None) if isinstance(entry, dict) else None
            if value is None and isinstance(entry, dict) and entry.get("value") is None:
                value = 0.0  # too few impacts of that kind to estimate it from
            if not _number(value) or not 0.0 <= value <= MAX_SCATTER:
                raise _fit_error(path, f"scatter.{kind}.{key} is not in [0, {MAX_SCATTER:g}]")
            spreads[name] = float(value)
    power = record.get("power", {"value": 1.0}) if isinstance(record, dict) else None
    power = power.get("value") if isinstance(power, dict) else None
    if not _number(power) or not 0.0 <= power <= registry.MAX_POWER:
        raise _fit_error(path, f"scatter.power.value is not in [0, {registry.MAX_POWER:g}]")
    shape = {}
    for name in registry.SCATTER_SHAPE:  # the jump's shape (absent: the null value, the Gaussian law)
        key = registry.config_key_specs()["scatter"][name]
        entry = record.get(name) if isinstance(record, dict) else None
        value = entry.get("value") if isinstance(entry, dict) else (key.default if entry is None else None)
        if not _number(value) or not key.low <= value <= key.high:
            raise _fit_error(path, f"scatter.{name}.value is not in [{key.low:g}, {key.high:g}]")
        shape[name] = float(value)
    scale = _scale_of(data)
    if scale is not None:  # the factor fit_scatter_scale chose on the selection tracks
        value = scale.get("value") if isinstance(scale, dict) else None
        if not _number(value) or not 0.0 < value <= MAX_SCALE:
            raise _fit_error(path, f"scatter_scale.value is not in (0, {MAX_SCALE:g}]")
        spreads = scaled_scatter(spreads, value)
    return {**spreads, "power": float(power), **shape}


def _scale_of(data):
    """A fit JSON's ``scatter_scale`` (checked by :func:`_scatter_of`), or None."""
    return data.get("scatter_scale")


def scattered(cfg, spreads, seed):
    """``cfg`` with the stochastic impact law at ``spreads`` ([scatter] keys: corner, flat and
    their floors; None: as it is)."""
    if not spreads:
        return cfg
    return dataclasses.replace(cfg, scatter=dataclasses.replace(cfg.scatter, **spreads, seed=seed))


def _parameter_draws(data, params, names, path):
    """(draws, sds, note): the JSON's bootstrap draws, or Gaussian sds from its ci95."""
    record = data.get("bootstrap_draws")
    if isinstance(record, dict) and record.get("names") and record.get("values"):
        columns = list(record["names"])
        if set(columns) != set(names):
            raise _fit_error(path, f"bootstrap_draws.names ({', '.join(columns)}) are not its parameters ({', '.join(names)})")
        try:
            table = np.array(record["values"], dtype=float)
        except (TypeError, ValueError):
            raise _fit_error(path, "bootstrap_draws.values is not a table of numbers") from None
        if table.ndim != 2 or table.shape[1] != len(columns) or not np.isfinite(table).all():
            raise _fit_error(path, f"bootstrap_draws.values is not a finite table of {len(columns)} columns")
        order = [columns.index(name) for name in names]
        return table[:, order], None, f"{table.shape[0]} bootstrap draws of the fit (one-step bootstrap over tracks)"
    sd = np.zeros(len(names))
    for k, name in enumerate(names):
        interval = params[name].get("ci95") if isinstance(params[name], dict) else None
        if isinstance(interval, list) and len(interval) == 2 and all(_number(v) for v in interval):
            sd[k] = (interval[1] - interval[0]) / (2.0 * Z95)
    note = ("no bootstrap_draws in the fit JSON: independent Gaussians from each parameter's ci95 "
            "(sd = width / 3.92; correlations between parameters left out)")
    if not sd.any():
        note = "no bootstrap_draws and no ci95 in the fit JSON: the parameters are held at their values (no parameter uncertainty)"
    return None, sd, note


BOUND_SLACK = 1e-9  # relative: a value the fit put on a bound, printed and read back


def check_fit_values(data, source, cfg, path):
    """Refuse a fit JSON edited by hand (issue 32) before anything is forecast from it: a
    ``model`` that is no contact model, a value or a bootstrap draw outside its registry
    bounds, a split whose confirmation share leaves no track to fit on (or none held out)."""
    from dice_sweep.config import CONTACT_MODELS

    model = data.get("model")
    if model is not None and model not in CONTACT_MODELS:
        raise _fit_error(path, f"model: {model!r} is not a contact model (allowed: {', '.join(CONTACT_MODELS)})")
    bounds = {name: registry.param(name).bounds_of(cfg) for name in source.names}
    rows = [("params", {name: source.params[name] for name in source.names})]
    if source.draws is not None:
        rows += [(f"bootstrap_draws.values[{k}]", dict(zip(source.names, row))) for k, row in enumerate(source.draws)]
    for key, values in rows:
        for name, value in values.items():
            low, high = bounds[name]
            slack = BOUND_SLACK * max(1.0, abs(low), abs(high)) if math.isfinite(high - low) else BOUND_SLACK
            if not low - slack <= value <= high + slack:
                raise _fit_error(path, f"{key}: {name} = {value:g} is outside its bounds [{low:g}, {high:g}] (docs/effects.md)")
    if not 0.0 < source.confirm_fraction < 1.0:
        raise _fit_error(path, f"split.confirm_fraction: {source.confirm_fraction:g} leaves no track to fit on or none held out "
                               "(allowed: between 0 and 1, as the fit wrote it)")


def check_split(data, source, trackset, path):
    """Refuse a fit whose split, applied to ``trackset``, cannot be the one it was made on: fewer
    tracks on either side than the fit says it fitted (``train_tracks``) or scored
    (``test_tracks``), so that the held-out tracks would include fitted ones."""
    select_set, confirm_set = trackset.split(source.confirm_fraction, source.seed)
    for key, held in (("train_tracks", select_set), ("test_tracks", confirm_set)):
        claimed = data.get(key)
        if _number(claimed) and claimed > len(held.tracks):
            raise _fit_error(path, f"{key}: {claimed:g} tracks, but its split (confirm_fraction {source.confirm_fraction:g}, seed "
                                   f"{source.seed}) of {trackset.path} has {len(held.tracks)} there: a split of other data, or edited")


def sample_params(source, cfg, count, rng):
    """``count`` parameter dicts: draws of the bootstrap (without replacement when there are
    enough), or of the Gaussians, clipped to the registry's bounds."""
    names = source.names
    if source.draws is not None:
        rows = rng.choice(len(source.draws), size=count, replace=len(source.draws) < count)
        table = source.draws[rows]
    else:
        centre = np.array([source.params[n] for n in names])
        table = centre + rng.normal(size=(count, len(names))) * source.sd
    bounds = np.array([registry.param(n).bounds_of(cfg) for n in names])
    table = np.clip(table, bounds[:, 0], bounds[:, 1])
    return [dict(zip(names, map(float, row))) for row in table]


# --- the model at given parameter values -----------------------------------------------------


def true_states(cfg, values, states):
    """States (n, 6) in the file's units -> the kernel's (the measurement effects at ``values``)."""
    _, state_to_true, _ = registry.measurement_maps(cfg, values)
    return np.ascontiguousarray(state_to_true(np.asarray(states, dtype=float)))


def roll(cfg_physical, states, streams=None):
    """(outcome, status) of the mapper on ``states`` (kernel units) to rest, in this process;
    ``streams`` (N, 2): each roll's random stream of the stochastic impact law."""
    rolls = Mapper.from_config(cfg_physical).roll(np.ascontiguousarray(states, dtype=np.float64), streams=streams)
    return rolls.outcome, rolls.status


def clear_starts(cfg, states):
    """bool (n,): starts with no corner inside the table or a wall."""
    return clear_of_surfaces(cfg.die.sides, cfg.die.circumradius, cfg.walls.separation, states, cfg.effects.corner_radius)


# --- what was seen: flights and resting sides ------------------------------------------------


@dataclass(frozen=True)
class FlightState:
    """The state at the first frame of one flight, from that flight's frames alone."""

    traj: int
    state: np.ndarray  # (6,) x, y, phi, vx, vy, omega in the file's units
    cov: np.ndarray  # (6, 6), Birge-inflated
    birge: float  # the flight's reduced chi-square (the covariance is multiplied by max(1, it))
    frames: int
    t0: float  # s, file time of the flight's first frame


def observed_side(track, cfg, values=None):
    """The side a track's die rests on (the side below its centre, averaged over its last
    still frames), or None when it does not end at rest."""
    pose = rest_pose(track.x, track.y, track.phi, track.usable, cfg.die.circumradius, track.t)
    if pose is None:
        return None
    state = true_states(cfg, values or {}, np.array([[*pose, 0.0, 0.0, 0.0]]))
    return int(side_below(cfg.die.sides, state[0, 2]))


def flight_states(cfg, spec, params, prepared, bounce, sigma):
    """:class:`FlightState` of flight ``bounce`` of every prepared track that has one.

    The states are fitted by the kernel (``fit_spec`` with the parameters held) to the flight's
    own frames; the covariance is that of the Gauss-Newton normal matrix with the tracking
    noise ``sigma`` (x, y in m, phi in rad), times the Birge ratio when above 1.
    """
    pieces = []
    for prep in prepared:
        if len(prep.flights) <= bounce:
            continue
        first, last = prep.flights[bounce]
        rows = slice(first, last + 1)
        pieces.append(shooting.PreparedTrack(prep.traj, prep.t[rows], prep.pose[rows], ((0, last - first),), math.nan))
    if not pieces:
        return []
    segments = shooting.Segments(pieces, params.get("g", cfg.world.g))
    held = shooting.fit_spec(cfg, spec, segments, start=params, fixed=True)
    lin = shooting.linearise(cfg, held, segments, free=())
    scale = np.array([sigma[0], sigma[1], cfg.die.circumradius * sigma[2]])
    jac = lin.jac_states / scale[None, :, None]
    residual = lin.residual / scale[None, :]
    hessian, _ = segment_products(jac, np.ones(len(residual)), residual, segments.starts)
    chi2 = segment_sums(np.sum(residual**2, axis=1), segments.starts)
    out = []
    for s, piece in enumerate(pieces):
        frames = int(segments.starts[s + 1] - segments.starts[s])
        dof = max(3 * frames - 6, 1)
        birge = float(chi2[s] / dof)
        cov = np.linalg.pinv(hessian[s]) * max(1.0, birge)
        out.append(FlightState(piece.traj, held.states[s].copy(), 0.5 * (cov + cov.T), birge, frames, float(piece.t[0])))
    return out


def _gaussian_factor(cov):
    """A matrix L with L L^T = cov (eigen-decomposition: cov may be singular)."""
    values, vectors = np.linalg.eigh(cov)
    return vectors * np.sqrt(np.clip(values, 0.0, None))


# --- the ensemble ------------------------------------------------------------------------------


class _DrawTask:
    """Picklable task: item j rolls, for every track, ``per_draw`` members of parameter draw j
    (their states drawn from the tracks' Gaussians with the generator seeded by (seed, bounce, j),
    starts inside the table drawn again). Returns (outcome (tracks, per_draw) int8, -2 for a
    member dropped, redraws)."""

    def __init__(self, cfg, spec, draws, means, factors, per_draw, seed, bounce, scatter=None):
        self.cfg, self.spec, self.draws = cfg, spec, draws
        self.means, self.factors = means, factors
        self.per_draw, self.seed, self.bounce = per_draw, seed, bounce
        self.scatter = scatter

    def __call__(self, j):
        values = self.draws[j]
        rng = np.random.default_rng([self.seed, self.bounce, j])
        tracks, m = len(self.means), self.per_draw
        file_states = self.means[:, None, :] + np.einsum("tij,tmj->tmi", self.factors, rng.normal(size=(tracks, m, 6)))
        states = true_states(self.cfg, values, file_states.reshape(-1, 6))
        clear = clear_starts(self.cfg, states)
        redraws = int((~clear).sum())
        for _ in range(REDRAWS):
            bad = np.flatnonzero(~clear)
            if not bad.size:
                break
            owner = bad // m
            fresh = self.means[owner] + np.einsum("bij,bj->bi", self.factors[owner], rng.normal(size=(bad.size, 6)))
            states[bad] = true_states(self.cfg, values, fresh)
            clear[bad] = clear_starts(self.cfg, states[bad])
        outcome = np.full(len(states), -2, np.int8)
        if clear.any():
            physical = scattered(kernel_config(self.cfg, self.spec, values), self.scatter, self.seed)
            # one stream per member: (member of this draw, forecast point and parameter draw)
            streams = np.column_stack([np.flatnonzero(clear), np.full(int(clear.sum()), self.bounce * STREAMS_PER_BOUNCE + j)])
            got, status = roll(physical, states[clear], streams if self.scatter else None)
            outcome[clear] = np.where(status == 0, got, -1)
        return outcome.reshape(tracks, m), redraws


@dataclass
class BounceForecast:
    """The ensembles of one forecast point: per track, side counts and what else was seen."""

    bounce: int
    traj: np.ndarray  # (tracks,)
    observed: np.ndarray  # (tracks,) side at rest
    counts: np.ndarray  # (tracks, n) members per side
    undecided: np.ndarray  # (tracks,) members without a side (status other than decided)
    dropped: np.ndarray  # (tracks,) members whose start stayed inside the table
    deterministic: np.ndarray  # (tracks,) side of the best-fit state and parameters (-1: none)
    flights: list  # FlightState per track
    redraws: int  # starts drawn again

    @property
    def probabilities(self):
        return probabilities(self.counts)


def ensemble_forecast(cfg, source, flights, observed, *, bounce, members=DEFAULT_MEMBERS, param_draws=PARAM_DRAWS, seed=0, workers=1,
                      draws=None):
    """The ensembles of one forecast point (:class:`BounceForecast`) for ``flights`` (their
    :class:`FlightState`) with resting sides ``observed`` (traj -> side). ``draws``: the
    parameter dicts to use (default: ``param_draws`` sampled from ``source``)."""
    spec = source.spec(cfg)
    if draws is None:
        draws = sample_params(source, cfg, min(param_draws, members), np.random.default_rng([seed, 1]))
    per_draw = -(-members // len(draws))
    means = np.array([f.state for f in flights]).reshape(-1, 6)
    factors = np.array([_gaussian_factor(f.cov) for f in flights]).reshape(-1, 6, 6)
    n = cfg.die.sides
    best = kernel_config(cfg, spec, source.params)
    deterministic = np.full(len(flights), -1, np.int64)
    if flights:
        outcome, status = roll(best, true_states(cfg, source.params, means))  # also compiles before the workers fork
        deterministic = np.where(status == 0, outcome, -1).astype(np.int64)
        if source.scatter:  # and the stochastic law's batch, which the workers roll
            roll(scattered(best, source.scatter, seed), true_states(cfg, source.params, means[:1]), np.zeros((1, 2)))
    task = _DrawTask(cfg, spec, draws, means, factors, per_draw, seed, bounce, source.scatter)
    results = ordered_map(task, len(draws), max(1, min(workers, len(draws)))) if flights else []
    outcomes = np.concatenate([r[0] for r in results], axis=1) if results else np.zeros((len(flights), 0), np.int8)
    counts = np.stack([(outcomes == side).sum(axis=1) for side in range(n)], axis=1) if flights else np.zeros((0, n), np.int64)
    return BounceForecast(bounce, np.array([f.traj for f in flights], dtype=np.int64),
                          np.array([observed[f.traj] for f in flights], dtype=np.int64), counts,
                          (outcomes == -1).sum(axis=1), (outcomes == -2).sum(axis=1), deterministic, list(flights),
                          int(sum(r[1] for r in results)))


def prepared_tracks(tracks, cfg, sigma, table, observed):
    """Prepared tracks (fit.prepare_tracks) of those of ``tracks`` with a resting side in
    ``observed`` (traj -> side or None)."""
    prepared = shooting.prepare_tracks(SimpleNamespace(tracks=tuple(tracks)), cfg, noise=np.asarray(sigma, dtype=float), table=table)
    return [p for p in prepared if observed.get(p.traj) is not None]


def flight_counts(prepared):
    """Tracks with a flight K, for K = 0, 1, ...: a list."""
    most = max((len(p.flights) for p in prepared), default=0)
    return [sum(len(p.flights) > k for p in prepared) for k in range(most)]


def forecast_bounces(prepared, cfg, source, bounces, *, sigma, observed, members=DEFAULT_MEMBERS, param_draws=PARAM_DRAWS, seed=0,
                     workers=1, log=None, label="tracks"):
    """{K: :class:`BounceForecast`} of the prepared tracks for every K in ``bounces`` (the same
    parameter draws for every K)."""
    say = log or (lambda message: None)
    spec = source.spec(cfg)
    draws = sample_params(source, cfg, min(param_draws, members), np.random.default_rng([seed, 1]))
    out = {}
    for bounce in bounces:
        flights = flight_states(cfg, spec, source.params, prepared, bounce, sigma)
        out[bounce] = ensemble_forecast(cfg, source, flights, observed, bounce=bounce, members=members, seed=seed, workers=workers,
                                        draws=draws)
        say(f"{label}, from flight {bounce}: {len(flights)} tracks, {int(out[bounce].counts.sum())} members with a side")
    return out


def forecast_tracks(tracks, cfg, source, *, sigma, table=0.0, bounces=(0,), members=DEFAULT_MEMBERS, param_draws=PARAM_DRAWS, seed=0,
                    workers=1, observed=None, log=None):
    """Ensembles of every forecast point in ``bounces`` for the tracks (a sequence of
    :class:`~dice_sweep.measured.tracks.Track`) that end at rest. ``observed`` (traj -> side)
    replaces the resting side read from the tracks (synthetic tracks that stop before rest).
    Returns ({bounce: BounceForecast}, the prepared tracks, {traj: side or None})."""
    if observed is None:
        observed = {track.traj: observed_side(track, cfg, source.params) for track in tracks}
    prepared = prepared_tracks(tracks, cfg, sigma, table, observed)
    out = forecast_bounces(prepared, cfg, source, bounces, sigma=sigma, observed=observed, members=members, param_draws=param_draws,
                           seed=seed, workers=workers, log=log)
    return out, prepared, observed


# --- one scale of the stochastic law, chosen by the forecasts' own log score (issue 31) ----------

# factors tried on every spread and floor of the fitted law, sqrt(2) apart
SCALE_GRID = (0.35, 0.5, 0.71, 1.0, 1.41, 2.0, 2.83, 4.0)
SCALE_MEMBERS = 250  # members per track, forecast point and factor (common random numbers across factors)
MAX_SCALE = 100.0  # a scale read from a fit JSON: above it every spread is at MAX_SCATTER anyway


def scaled_scatter(spreads, scale):
    """The law's spreads and floors times ``scale``, each capped at MAX_SCATTER; its form (the
    power) as it is (None stays None)."""
    scaled = set(registry.scatter_spread_keys())
    return None if spreads is None else {key: min(value * scale, MAX_SCATTER) if key in scaled else value for key, value in spreads.items()}


def _peak(x, y):
    """(argmax, at an end): the vertex of the parabola through the best of ``y`` over ``x`` and its two
    neighbours, kept between them; the end point itself when the best is at an end."""
    i = int(np.argmax(y))
    if i == 0 or i == len(x) - 1:
        return float(x[i]), True
    (x0, x1, x2), (y0, y1, y2) = x[i - 1:i + 2], y[i - 1:i + 2]
    den = (x0 - x1) * (y0 - y2) - (x0 - x2) * (y0 - y1)
    if den == 0.0:
        return float(x1), False
    vertex = x0 - 0.5 * ((x0 - x1) ** 2 * (y0 - y2) - (x0 - x2) ** 2 * (y0 - y1)) / den
    return float(np.clip(vertex, x0, x2)), False


def fit_scatter_scale(prepared, cfg, source, bounces, *, sigma, observed, grid=SCALE_GRID, members=SCALE_MEMBERS, param_draws=PARAM_DRAWS,
                      seed=0, workers=1, draws=BOOTSTRAP, log=None):
    """One factor c on every spread and floor of ``source.scatter``, the same for every forecast
    point: the c whose forecasts of the ``prepared`` tracks (the selection tracks: never those
    to be scored) from every flight in ``bounces`` have the highest summed log score (a proper
    scoring rule, so the c that makes the ensemble's spread match how often its sides happen;
    the peak of a parabola in log c through the best factor of ``grid`` and its neighbours),
    with a 95 % interval from a bootstrap over tracks (each track with all its forecast points).
    The same members (random streams) for every factor, so the differences between factors are
    not sampling noise. Returns a JSON-ready dict (``value`` 1: the law as estimated)."""
    say = log or (lambda message: None)
    spec = source.spec(cfg)
    params = sample_params(source, cfg, min(param_draws, members), np.random.default_rng([seed, 1]))
    trajs = sorted({p.traj for p in prepared})
    row = {traj: i for i, traj in enumerate(trajs)}
    flights = {k: flight_states(cfg, spec, source.params, prepared, k, sigma) for k in bounces}
    scores = np.zeros((len(trajs), len(grid)))
    for g, factor in enumerate(grid):
        scaled = dataclasses.replace(source, scatter=scaled_scatter(source.scatter, factor))
        for k in bounces:
            if flights[k]:
                bf = ensemble_forecast(cfg, scaled, flights[k], observed, bounce=k, members=members, seed=seed, workers=workers,
                                       draws=params)
                np.add.at(scores[:, g], [row[t] for t in bf.traj], log_scores(bf.probabilities, bf.observed))
        say(f"scatter scale x {factor:g}: summed log score {scores[:, g].sum():.2f} over {len(trajs)} tracks")
    x = np.log(np.asarray(grid, dtype=float))
    value, at_end = _peak(x, scores.sum(axis=0))
    rng = np.random.default_rng([seed, 3133])
    counts = rng.multinomial(len(trajs), np.full(len(trajs), 1.0 / len(trajs)), size=draws)
    boot = np.exp([_peak(x, c @ scores)[0] for c in counts])
    pairs = sum(len(f) for f in flights.values())
    return {"value": float(math.exp(value)), "ci95": _interval(boot), "at_grid_end": at_end, "grid": [float(v) for v in grid],
            "mean_log_score": [float(v) for v in scores.sum(axis=0) / max(pairs, 1)], "tracks": len(trajs), "pairs": int(pairs),
            "bounces": [int(k) for k in bounces], "members": int(members),
            "rule": "one factor on every [scatter] spread and floor, the same at every forecast point, maximising the summed log "
                    "score of the selection tracks' forecasts from every flight (parabola in log factor through the best grid "
                    "point); 95 % interval: bootstrap over tracks"}


@dataclass
class ForecastRun:
    """Everything one forecast of a track file computed (:func:`run_forecast`)."""

    from_bounce: int
    held_out: dict  # K -> BounceForecast on the confirmation tracks
    selection: dict  # K -> BounceForecast on the selection tracks (for the recalibration)
    observed: dict  # traj -> side at rest (None: not at rest)
    counts: dict  # what was left out, and why
    release: list  # FlightState of flight 0 of every track at rest (both sets), for the map
    held_out_traj: set


def check_from_bounce(from_bounce):
    """The static range of --from-bounce (the tracks may allow less)."""
    top = shooting.MAX_FLIGHTS - 1
    if not 0 <= from_bounce <= top:
        raise DiceSweepError(f"--from-bounce: {from_bounce} is outside the allowed range [0, {top}] "
                             f"(the fit follows the first {shooting.MAX_FLIGHTS} flights of a track)")


def check_members(members):
    if not MIN_MEMBERS <= members <= 10**6:
        raise DiceSweepError(f"--members: {members} is outside the allowed range [{MIN_MEMBERS}, 1000000] "
                             f"(fewer members cannot resolve probabilities of a few per cent)")


def run_forecast(trackset, cfg, source, *, sigma, table=0.0, from_bounce=0, members=DEFAULT_MEMBERS, param_draws=PARAM_DRAWS, seed=0,
                 workers=1, recalibrate=True, log=None, intro=None):
    """Forecasts of the held-out tracks of ``trackset`` (the confirmation set of the fit's split)
    from every flight K that at least MIN_BOUNCE_TRACKS of them have (and ``from_bounce``), and,
    with ``recalibrate``, of the selection tracks (which fit the blend with the uniform
    forecast). One-line error when no held-out track has flight ``from_bounce``."""
    check_from_bounce(from_bounce)
    select_set, confirm_set = trackset.split(source.confirm_fraction, source.seed)
    observed = {track.traj: observed_side(track, cfg, source.params) for track in trackset.tracks}
    confirm = prepared_tracks(confirm_set.tracks, cfg, sigma, table, observed)
    held = flight_counts(confirm)
    if from_bounce >= len(held):
        raise DiceSweepError(f"--from-bounce: {from_bounce}: no held-out track at rest has a flight {from_bounce} "
                             f"(allowed: 0 to {len(held) - 1} for {trackset.path})")
    bounces = [k for k, count in enumerate(held) if count >= MIN_BOUNCE_TRACKS or k == from_bounce]
    if log and intro:
        log(intro)
    options = dict(sigma=sigma, observed=observed, members=members, param_draws=param_draws, seed=seed, workers=workers, log=log)
    held_out = forecast_bounces(confirm, cfg, source, bounces, label="held-out tracks", **options)
    select = prepared_tracks(select_set.tracks, cfg, sigma, table, observed)
    # the blend's one weight needs far fewer members than a scored forecast
    options["members"] = min(members, SELECTION_MEMBERS)
    selection = forecast_bounces(select, cfg, source, bounces, label="selection tracks", **options) if recalibrate and select else {}
    if 0 in selection:
        release = selection[0].flights + held_out[0].flights
    else:
        release = flight_states(cfg, source.spec(cfg), source.params, select, 0, sigma) + (held_out[0].flights if 0 in held_out else [])
    counts = {"tracks": len(trackset.tracks), "held_out": len(confirm_set.tracks), "selection": len(select_set.tracks),
              "not_at_rest": sum(side is None for side in observed.values()),
              "held_out_scored": len(confirm), "selection_scored": len(select), "held_out_with_flight": held}
    return ForecastRun(from_bounce, held_out, selection, observed, counts, release, {t.traj for t in confirm_set.tracks})


# --- scores ------------------------------------------------------------------------------------


def probabilities(counts, smoothing=SMOOTHING):
    """Side probabilities from member counts (tracks, n): (count + a) / (members + n a)."""
    counts = np.asarray(counts, dtype=float)
    return (counts + smoothing) / (counts.sum(axis=-1, keepdims=True) + smoothing * counts.shape[-1])


def one_hot(sides, n):
    """(tracks, n) with 1 at each track's side (a side of -1 gives a row of zeros)."""
    sides = np.asarray(sides)
    return (sides[:, None] == np.arange(n)[None, :]).astype(float)


def log_scores(prob, observed):
    """Per track, the natural log of the probability given to the side that happened."""
    prob = np.asarray(prob, dtype=float)
    with np.errstate(divide="ignore"):
        return np.log(prob[np.arange(len(prob)), np.asarray(observed)])


def brier_scores(prob, observed):
    """Per track, sum over the sides of (p_k - [k happened])^2 (0 perfect, 2 sure and wrong)."""
    prob = np.asarray(prob, dtype=float)
    return np.sum((prob - one_hot(observed, prob.shape[1])) ** 2, axis=1)


def deterministic_probabilities(sides, n, members, smoothing=SMOOTHING):
    """A deterministic forecast as an ensemble of ``members`` identical members (so that its
    log score is finite when wrong: ln(a / (members + n a))); no side (-1) gives 1/n."""
    counts = one_hot(sides, n) * members
    prob = probabilities(counts, smoothing)
    prob[np.asarray(sides) < 0] = 1.0 / n
    return prob


def wilson_interval(hits, count, z=Z95):
    """95 % Wilson score interval of a binomial share."""
    if count == 0:
        return [math.nan, math.nan]
    share = hits / count
    centre = (share + z * z / (2 * count)) / (1 + z * z / count)
    half = z * math.sqrt(share * (1 - share) / count + z * z / (4 * count * count)) / (1 + z * z / count)
    return [centre - half, centre + half]


def reliability(prob, observed, bins=RELIABILITY_BINS):
    """The reliability diagram: every (track, side) pair binned by its predicted probability.

    Per bin: its edges, the pairs, their mean predicted probability, the share of them that
    happened with its 95 % Wilson interval, and the binomial standard deviation of that share
    if the forecast were calibrated (sqrt(sum p (1 - p)) / pairs).
    """
    prob = np.asarray(prob, dtype=float)
    hit = one_hot(observed, prob.shape[1]).ravel()
    p = prob.ravel()
    edges = np.linspace(0.0, 1.0, bins + 1)
    index = np.clip(np.searchsorted(edges, p, side="right") - 1, 0, bins - 1)
    out = []
    for b in range(bins):
        inside = index == b
        count = int(inside.sum())
        entry = {"p_low": float(edges[b]), "p_high": float(edges[b + 1]), "pairs": count}
        if count:
            hits = int(hit[inside].sum())
            entry.update(mean_predicted=float(p[inside].mean()), observed_frequency=hits / count,
                         ci95=wilson_interval(hits, count),
                         calibrated_sd=float(math.sqrt(np.sum(p[inside] * (1 - p[inside]))) / count))
        out.append(entry)
    return out


def calibration_test(prob, observed):
    """z-scores of the summed log and Brier scores against their mean and variance if every
    side happened with the forecast's probability (tracks independent). |z| above 2 to 3 says
    the forecast is miscalibrated (negative: the sides that happened were less likely than it
    said, i.e. overconfident)."""
    prob = np.asarray(prob, dtype=float)
    logs = np.log(prob)
    expected_log = np.sum(prob * logs, axis=1)
    var_log = np.sum(prob * logs**2, axis=1) - expected_log**2
    square = np.sum(prob**2, axis=1)
    expected_brier = 1.0 - square
    var_brier = 4.0 * (np.sum(prob**3, axis=1) - square**2)
    got_log, got_brier = log_scores(prob, observed), brier_scores(prob, observed)

    def z(got, mean, var):
        total = float(np.sum(var))
        return float(np.sum(got - mean) / math.sqrt(total)) if total > 0 else math.nan

    return {"expected_log_score": float(np.mean(expected_log)), "log_score_z": z(got_log, expected_log, var_log),
            "expected_brier": float(np.mean(expected_brier)), "brier_z": -z(got_brier, expected_brier, var_brier),
            "rule": "z = (sum over tracks of score - its expectation under the forecast) / sqrt(sum of its variances); "
                    "negative: the forecast was more confident than the outcomes bear out (brier_z signed the same way)"}


def bootstrap_means(columns, rng, draws=BOOTSTRAP):
    """Means over resampled tracks of each column of ``columns`` (tracks, k): (draws, k), the
    same resamples for every column (paired differences)."""
    columns = np.asarray(columns, dtype=float).reshape(len(columns), -1)
    index = rng.integers(0, len(columns), size=(draws, len(columns)))
    return columns[index].mean(axis=1)


def _interval(values):
    return [float(np.quantile(values, 0.025)), float(np.quantile(values, 0.975))]


def _entry(value, samples):
    return {"value": float(value), "ci95": _interval(samples)}


def fit_blend(prob, observed):
    """The weight w in [0, 1] of the uniform forecast in (1 - w) p + w / n that maximises the
    mean log score of ``prob`` on the ``observed`` sides (the log score is concave in w)."""
    from scipy.optimize import minimize_scalar

    prob = np.asarray(prob, dtype=float)
    got = prob[np.arange(len(prob)), np.asarray(observed)]
    n = prob.shape[1]
    if not len(got):
        return 0.0
    best = minimize_scalar(lambda w: -np.mean(np.log((1.0 - w) * got + w / n)), bounds=(0.0, 1.0), method="bounded",
                           options={"xatol": 1e-6})
    return float(best.x)


def blend(prob, weight):
    """(1 - weight) p + weight / n."""
    prob = np.asarray(prob, dtype=float)
    return (1.0 - weight) * prob + weight / prob.shape[1]


def _scores(prob, observed, rng, draws, bins, references=()):
    """Log score, Brier score and, against each (name, probabilities) of ``references``, the
    paired skills, with 95 % intervals (one bootstrap over tracks for all); reliability and the
    calibration test."""
    n = prob.shape[1]
    uniform = np.full(prob.shape, 1.0 / n)
    columns = [log_scores(prob, observed), brier_scores(prob, observed), log_scores(uniform, observed), brier_scores(uniform, observed)]
    for _, ref in references:
        columns += [log_scores(ref, observed), brier_scores(ref, observed)]
    columns = np.column_stack(columns)
    boot, mean = bootstrap_means(columns, rng, draws), columns.mean(axis=0)
    out = {"log_score": _entry(mean[0], boot[:, 0]), "log_score_uniform": _entry(mean[2], boot[:, 2]),
           "brier": _entry(mean[1], boot[:, 1]), "brier_uniform": _entry(mean[3], boot[:, 3]),
           "log_skill": _entry(mean[0] - mean[2], boot[:, 0] - boot[:, 2]),
           "brier_skill": _entry(1.0 - mean[1] / mean[3], 1.0 - boot[:, 1] / boot[:, 3])}
    for k, (name, _) in enumerate(references):
        a, b = 4 + 2 * k, 5 + 2 * k
        out[f"log_score_{name}"] = _entry(mean[a], boot[:, a])
        out[f"brier_{name}"] = _entry(mean[b], boot[:, b])
        out[f"log_skill_{name}"] = _entry(mean[a] - mean[2], boot[:, a] - boot[:, 2])
        out[f"log_skill_over_{name}"] = _entry(mean[0] - mean[a], boot[:, 0] - boot[:, a])
    entropy = -np.sum(prob * np.log(prob), axis=1)
    out["mean_entropy"] = float(entropy.mean())
    out["mean_p_max"] = float(prob.max(axis=1).mean())
    out["calibration"] = calibration_test(prob, observed)
    out["reliability"] = reliability(prob, observed, bins)
    return out, columns


def score_bounce(fc, n, rng, selection=None, draws=BOOTSTRAP, bins=RELIABILITY_BINS):
    """The scores of one forecast point, JSON-ready: the ensemble's log and Brier scores beside
    the uniform and the deterministic forecast, with 95 % intervals (bootstrap over tracks) and
    paired skills; shares correct; reliability; calibration test; per track. With the
    ``selection`` tracks' forecast of the same point: ``recalibrated``, the blend with the
    uniform forecast whose weight maximises their mean log score, scored here."""
    tracks = len(fc.traj)
    members = int(np.median(fc.counts.sum(axis=1))) if tracks else 0
    out = {"from_bounce": int(fc.bounce), "n_tracks": tracks, "members": members}
    if tracks == 0:
        return out
    prob = fc.probabilities
    det = deterministic_probabilities(fc.deterministic, n, max(members, 1))
    scores, columns = _scores(prob, fc.observed, rng, draws, bins, references=[("deterministic", det)])
    out.update(scores)
    likely = np.argmax(prob, axis=1)
    hits = np.column_stack([fc.deterministic == fc.observed, likely == fc.observed]).astype(float)
    boot = bootstrap_means(hits, rng, draws)
    out["share_correct_deterministic"] = _entry(hits[:, 0].mean(), boot[:, 0])
    out["share_correct_most_likely"] = _entry(hits[:, 1].mean(), boot[:, 1])
    out["share_correct_uniform"] = 1.0 / n
    out["deterministic_rule"] = (f"the best-fit state and parameters rolled once; scored as an ensemble of {max(members, 1)} identical "
                                 f"members (a wrong side gets ln({SMOOTHING} / ({max(members, 1)} + {n} x {SMOOTHING})))")
    out["birge_median"] = float(np.median([f.birge for f in fc.flights]))
    out["members_undecided"] = int(fc.undecided.sum())
    out["members_dropped"] = int(fc.dropped.sum())
    out["starts_drawn_again"] = int(fc.redraws)
    if selection is not None and len(selection.traj):
        weight = fit_blend(selection.probabilities, selection.observed)
        blended, _ = _scores(blend(prob, weight), fc.observed, rng, draws, bins)
        out["recalibrated"] = {"weight_uniform": weight, "fitted_on_tracks": int(len(selection.traj)),
                               "rule": "(1 - w) p + w / n, w maximising the mean log score of the selection tracks' forecasts "
                                       "from the same flight; scored on the held-out tracks", **blended}
    out["tracks"] = [
        {"traj": int(fc.traj[i]), "observed": int(fc.observed[i]), "probabilities": [float(v) for v in prob[i]],
         "counts": [int(v) for v in fc.counts[i]], "deterministic": int(fc.deterministic[i]), "log_score": float(columns[i, 0]),
         "brier": float(columns[i, 1]), "birge": float(fc.flights[i].birge), "frames": int(fc.flights[i].frames),
         "state": [float(v) for v in fc.flights[i].state], "state_sd": [float(v) for v in np.sqrt(np.diag(fc.flights[i].cov))]}
        for i in range(tracks)
    ]
    return out


def score_run(run, n, seed=0, draws=BOOTSTRAP):
    """``scores`` (the point --from-bounce, with ``by_bounce``: every point) of a
    :class:`ForecastRun`, JSON-ready."""
    by_bounce = []
    for k in sorted(run.held_out):
        rng = np.random.default_rng([seed, 2, k])
        by_bounce.append(score_bounce(run.held_out[k], n, rng, run.selection.get(k), draws))
    scores = dict(next(b for b in by_bounce if b["from_bounce"] == run.from_bounce))
    scores["by_bounce"] = by_bounce
    return scores


# --- which forecast to trust, and what to warn about ---------------------------------------------

CALIBRATED_Z = 3.0  # |calibration z| of log and Brier at or below this: the forecast is calibrated
AT_BOUND = 1e-6  # a fitted value within this share of its range from a bound sits at it


def _calibrated(entry):
    cal = entry.get("calibration") if entry else None
    return bool(cal) and abs(cal["log_score_z"]) <= CALIBRATED_Z and abs(cal["brier_z"]) <= CALIBRATED_Z


def headline(scores):
    """(name, scores) of the forecast to print first: the ensemble when it is calibrated
    (|z| <= CALIBRATED_Z for log and Brier), else the recalibrated blend when that is, else the
    ensemble, named as not calibrated."""
    if _calibrated(scores):
        return "ensemble (calibrated)", scores
    recal = scores.get("recalibrated")
    if _calibrated(recal):
        return f"recalibrated ensemble (w = {recal['weight_uniform']:.3f}, calibrated; the raw ensemble is not)", recal
    return "ensemble (NOT calibrated)", scores


def warnings(scores, source, cfg):
    """One-line warnings: forecasts that score below the uniform one on the held-out tracks
    (any forecast point; the ensemble, the recalibrated and the deterministic one) and fitted
    parameters at a bound of their range."""
    below = []
    for b in scores.get("by_bounce", [scores]):
        for name, skill in (("ensemble", b.get("log_skill")), ("deterministic", b.get("log_skill_deterministic")),
                            ("recalibrated", (b.get("recalibrated") or {}).get("log_skill"))):
            if skill and skill["value"] < 0.0:
                below.append(f"{name} from flight {b['from_bounce']} ({skill['value']:.3f} nats)")
    out = []
    if below:
        out.append("below the uniform forecast on the held-out tracks: " + ", ".join(below))
    bounded = []
    for name, value in source.params.items():
        low, high = registry.param(name).bounds_of(cfg)
        width = high - low if math.isfinite(high - low) else max(abs(low), abs(high), 1.0)
        for side, bound in (("lower", low), ("upper", high)):
            if math.isfinite(bound) and abs(value - bound) <= AT_BOUND * width:
                bounded.append(f"{name} = {value:.4g} at its {side} bound")
    if bounded:
        out.append("fitted parameters at a bound: " + ", ".join(bounded))
    return out


# --- where the throws sit in the final-state map ------------------------------------------------


def natural_scales(cfg):
    """The die's own scale of each initial value: R, R, 2 pi / n, sqrt(g R), sqrt(g R), sqrt(g / R)."""
    radius, g, n = cfg.die.circumradius, cfg.world.g, cfg.die.sides
    speed = math.sqrt(g * radius)
    return np.array([radius, radius, 2 * math.pi / n, speed, speed, math.sqrt(g / radius)])


def phase_centre(phi, sides):
    """The circular mean of ``phi`` modulo 2 pi / n (rad)."""
    return float(np.angle(np.mean(np.exp(1j * sides * np.asarray(phi)))) / sides)


def fold_phase(phi, sides, centre):
    """(phi folded into [centre - pi/n, centre + pi/n), quarter turns m removed): folding by m
    turns of 2 pi / n raises the side below by m (mod n)."""
    period = 2 * math.pi / sides
    turns = np.floor((np.asarray(phi) - centre + 0.5 * period) / period).astype(np.int64)
    return np.asarray(phi) - turns * period, turns


def spreads(states, cfg):
    """Spread of each initial value over ``states`` (n, 6), in the die's natural scales:
    standard deviations, phi0 folded modulo 2 pi / n about its circular mean."""
    states = np.array(states, dtype=float).reshape(-1, 6)
    if len(states):
        states[:, 2], _ = fold_phase(states[:, 2], cfg.die.sides, phase_centre(states[:, 2], cfg.die.sides))
    return states.std(axis=0) / natural_scales(cfg)


def choose_map_axes(states, cfg):
    """The two initial values that vary most over the release states (in natural scales; x0
    only between walls: without them it changes nothing), the larger on the x axis."""
    spread = spreads(states, cfg)
    if cfg.walls.separation is None:
        spread[0] = -1.0
    first, second = np.argsort(-spread)[:2]
    return STATE_COLUMNS[first], STATE_COLUMNS[second]


MAP_PAD = 0.1  # share of the drops' range added on each side of a map axis


def map_range(values, param, cfg):
    """[low, high] of a map axis: one period 2 pi / n about the circular mean for phi0, else
    the drops' 0.5-99.5 % range widened by MAP_PAD on each side."""
    values = np.asarray(values, dtype=float)
    if param == "phi0":
        centre = phase_centre(values, cfg.die.sides)
        return centre - math.pi / cfg.die.sides, centre + math.pi / cfg.die.sides
    low, high = np.quantile(values, [0.005, 0.995])
    pad = MAP_PAD * max(high - low, 1e-6 * max(abs(high), abs(low), 1e-12))
    return float(low - pad), float(high + pad)


# --- the report in Markdown ---------------------------------------------------------------------


def _ci(entry, digits=3):
    if not isinstance(entry, dict) or entry.get("value") is None:
        return "-"
    low, high = entry["ci95"]
    return f"{entry['value']:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def _pct(entry):
    if not isinstance(entry, dict) or entry.get("value") is None:
        return "-"
    low, high = entry["ci95"]
    return f"{100 * entry['value']:.0f} % [{100 * low:.0f}, {100 * high:.0f}]"


def _z(calibration, key):
    value = calibration.get(key) if calibration else None
    return "-" if value is None else f"{value:.1f}"


def _scale_text(scale):
    """The factor on the law, as the report names it (a hand-written scatter_scale may hold its value only)."""
    if not isinstance(scale, dict):
        return ""
    interval = scale.get("ci95")
    text = f" (the spreads estimated from clean impacts times {scale['value']:.3f}"
    if isinstance(interval, list) and len(interval) == 2:
        text += f" [{interval[0]:.3f}, {interval[1]:.3f}]"
    if scale.get("tracks") and scale.get("bounces"):
        text += (f", the factor whose forecasts of {scale['tracks']} selection tracks from flights "
                 f"{', '.join(map(str, scale['bounces']))} score best")
    return text + (", at the end of the factors tried" if scale.get("at_grid_end") else "") + ")"


def markdown(report):
    """The forecast report (the JSON of ``dice-sweep forecast``) as Markdown."""
    scores, data, fit, ens = report["scores"], report["data"], report["fit"], report["ensemble"]
    k = scores["from_bounce"]
    n = 1.0 / scores["share_correct_uniform"]
    lines = ["# Side forecasts of tracked drops", ""]
    if report.get("warnings"):
        lines += ["**Warning:** " + "; ".join(report["warnings"]) + ".", ""]
    first = report.get("headline") or headline(scores)[0]
    lines += [
        f"The forecast to read first: the {first}.", "",
        f"Data: {data['path']}: {data['tracks']} tracks, {data['held_out']} held out by the fit's split "
        f"({data['held_out_scored']} scored: at rest, with a first flight), {data['selection_scored']} selection tracks "
        f"for the recalibration; {data['not_at_rest']} tracks not at rest at their end are left out.", "",
        f"Fit: {fit['path']} ({fit['kind']}): effects {', '.join(fit['effects']) or 'none'}; "
        + ", ".join(f"{name} = {value:.4g}" for name, value in fit["params"].items()) + f". Parameter uncertainty: {fit['parameter_uncertainty']}."
        + ("" if fit["same_data"] else f" The fit was made on {fit['data_path']}, not on this file: its split still decides which tracks are held out.")
        + (" Impacts drawn from the fitted stochastic law: [scatter] " + ", ".join(f"{k} = {v:.4g}" for k, v in fit["scatter"].items())
           + _scale_text(fit.get("scatter_scale")) + "."
           if fit.get("scatter") else " Impacts: the fitted law exactly (no [scatter] in the fit)."), "",
        f"Ensemble: {ens['members']} members per track and forecast point ({ens['param_draws']} parameter draws x "
        f"{ens['state_draws_per_param_draw']} state draws), seed {ens['seed']}; tracking noise sigma x {report['noise']['sigma_x'] * 1e3:.4f} mm, "
        f"y {report['noise']['sigma_y'] * 1e3:.4f} mm, phi {report['noise']['sigma_phi'] * 1e3:.3f} mrad.", "",
        f"## Held-out tracks, forecast from flight {k} ({'release' if k == 0 else f'after bounce {k}'}): {scores['n_tracks']} tracks", "",
        "| forecast | mean log score (nats) | Brier score | most likely side right |",
        "|---|---|---|---|",
        f"| ensemble | {_ci(scores['log_score'])} | {_ci(scores['brier'])} | {_pct(scores['share_correct_most_likely'])} |",
    ]
    recal = scores.get("recalibrated")
    if recal:
        row = (f"| recalibrated ensemble (w = {recal['weight_uniform']:.3f}) | {_ci(recal['log_score'])} | {_ci(recal['brier'])} | "
               f"{_pct(scores['share_correct_most_likely'])} |")
        if first.startswith("recalibrated"):
            lines.insert(len(lines) - 1, row)  # the calibrated forecast first
        else:
            lines.append(row)
    lines += [
        f"| deterministic | {_ci(scores['log_score_deterministic'])} | {_ci(scores['brier_deterministic'])} | "
        f"{_pct(scores['share_correct_deterministic'])} |",
        f"| uniform 1/{n:.0f} | {scores['log_score_uniform']['value']:.3f} | {scores['brier_uniform']['value']:.3f} | {100 / n:.0f} % |", "",
        f"Log skill over 1/n (nats, at most ln {n:.0f} = {math.log(n):.3f}): ensemble {_ci(scores['log_skill'])}, deterministic "
        f"{_ci(scores['log_skill_deterministic'])}" + (f", recalibrated {_ci(recal['log_skill'])}" if recal else "") + ". "
        f"Brier skill: ensemble {_ci(scores['brier_skill'])}" + (f", recalibrated {_ci(recal['brier_skill'])}" if recal else "") + ".", "",
        f"Calibration (z of the summed score against its expectation under the forecast; negative: overconfident): ensemble log "
        f"{_z(scores['calibration'], 'log_score_z')}, Brier {_z(scores['calibration'], 'brier_z')}"
        + (f"; recalibrated log {_z(recal['calibration'], 'log_score_z')}, Brier {_z(recal['calibration'], 'brier_z')}" if recal else "")
        + f". Mean entropy of the ensemble's probabilities {scores['mean_entropy']:.3f} nats (ln {n:.0f} = {math.log(n):.3f}); "
        f"median reduced chi-square of the flights {scores['birge_median']:.2f}.", "",
        f"Deterministic forecast: {scores['deterministic_rule']}.", "",
        "## By forecast point (held-out tracks)", "",
        "| from flight | tracks | log skill, ensemble | log skill, recalibrated (w) | log skill, deterministic | Brier skill, ensemble "
        "| most likely right | deterministic right | mean entropy | calibration z (log) | flights' chi2/dof |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for b in scores["by_bounce"]:
        if not b["n_tracks"]:
            continue
        r = b.get("recalibrated")
        lines.append(f"| {b['from_bounce']} | {b['n_tracks']} | {_ci(b['log_skill'])} | "
                     + (f"{_ci(r['log_skill'])} ({r['weight_uniform']:.2f})" if r else "-")
                     + f" | {_ci(b['log_skill_deterministic'])} | {_ci(b['brier_skill'])} | {_pct(b['share_correct_most_likely'])} | "
                     f"{_pct(b['share_correct_deterministic'])} | {b['mean_entropy']:.3f} | {_z(b['calibration'], 'log_score_z')} | "
                     f"{b['birge_median']:.2f} |")
    lines += ["", f"## Reliability, forecast from flight {k} (every track and side a pair)", "",
              "| predicted | pairs | mean predicted | observed | 95 % interval |" + (" recalibrated: pairs | mean predicted | observed |" if recal else ""),
              "|---|---|---|---|---|" + ("---|---|---|" if recal else "")]
    for i, b in enumerate(scores["reliability"]):
        row = f"| {b['p_low']:.1f}-{b['p_high']:.1f} | {b['pairs']} | "
        row += (f"{b['mean_predicted']:.3f} | {b['observed_frequency']:.3f} | [{b['ci95'][0]:.3f}, {b['ci95'][1]:.3f}] |" if b["pairs"] else "- | - | - |")
        if recal:
            c = recal["reliability"][i]
            row += f" {c['pairs']} | " + (f"{c['mean_predicted']:.3f} | {c['observed_frequency']:.3f} |" if c["pairs"] else "- | - |")
        lines.append(row)
    m = report.get("map")
    if m:
        be = m["measures"]["basin_entropy"]
        ax, ay = m["axes"]
        lines += ["", "## Where the throws sit in the final-state map", "",
                  f"A {m['size'][0]} x {m['size'][1]} map over {ax} {m['ranges'][ax][0]:.4g} to {m['ranges'][ax][1]:.4g} {m['units'][ax]} and "
                  f"{ay} {m['ranges'][ay][0]:.4g} to {m['ranges'][ay][1]:.4g} {m['units'][ay]} ({m['axes_rule']}), the other initial values "
                  "at the drops' medians (" + ", ".join(f"{name} = {value:.4g}" for name, value in m["fixed"].items())
                  + "), the fitted parameters." + (" phi0 is folded into one turn of 2 pi / n, the drops' sides renamed to match." if m["phi0_folded"] else ""), "",
                  f"- Basin entropy Sb = {be['Sb']:.4f} nats, boundary basin entropy Sbb = "
                  + ("-" if be["Sbb"] is None else f"{be['Sbb']:.3f}") + f" nats ({be['box_size_pixels']} x {be['box_size_pixels']} boxes; "
                  f"{be['boundary_boxes']} of {be['boxes']} boxes on a boundary); share of pixels uncertain at 1 pixel f(1) = {m['f_1_pixel']:.3f}; "
                  f"uncertainty exponent alpha = {m['alpha_text']}.",
                  f"- The drops ({m['drops_in_map']} of {m['drops']} inside the map): mean entropy of the box each sits in "
                  f"{m['drops_box_entropy_mean']:.3f} nats, {100 * m['drops_on_boundary_boxes']:.0f} % in boxes on a boundary; the map's side at "
                  f"a drop's place is the side it rested on for {100 * m['drops_side_as_map']:.0f} % (the other initial values differ from drop to drop).",
                  "- A release state's standard deviation (median over drops): " + ", ".join(f"{v:.2f} cells in {name}" for name, v in m["release_sd_in_cells"].items()) + "."]
    return "\n".join(lines) + "\n"


# The model-free forecast from the release (issue 31): how much the release states of the
# selection tracks tell about the side, with no physics, as a measure of what any forecast from
# the release could reach on these drops (not a bound: a better learner could do better)
NEIGHBOURS = (5, 10, 20, 40, 80, 160, None)  # k tried (None: every training track, the sides' base rates)
NEIGHBOUR_SMOOTHING = (0.25, 0.5, 1.0, 2.0)  # pseudo-counts per side tried
# the initial values used, as columns of (x, y, phi, vx, vy, omega): x is left out (a table
# without walls is the same everywhere), subsets tried because 250 tracks fill 5 dimensions thinly
NEIGHBOUR_FEATURES = ((1, 2, 3, 4, 5), (2, 5), (1, 2, 5), (2, 4, 5), (1, 2, 4, 5))


def folded_release(states, cfg, centre):
    """(features in the die's own scales with phi folded about ``centre``, the quarter turns
    m removed): a die turned by m turns of 2 pi / n rests on the side m higher (mod n)."""
    states = np.array(states, dtype=float).reshape(-1, 6)
    states[:, 2], turns = fold_phase(states[:, 2], cfg.die.sides, centre)
    return states / natural_scales(cfg), turns


def neighbour_probabilities(train, train_sides, test, n, k, smoothing, exclude_self=False):
    """(tests, n) side probabilities: the sides of the k training points nearest each test point
    (Euclidean), (count + smoothing) / (k + n smoothing); ``exclude_self``: test = train, each
    point's own side left out (leave-one-out)."""
    distance = np.sum((test[:, None, :] - train[None, :, :]) ** 2, axis=2)
    if exclude_self:
        np.fill_diagonal(distance, np.inf)
    k = min(k, train.shape[0] - int(exclude_self))
    nearest = np.argpartition(distance, k - 1, axis=1)[:, :k]
    counts = one_hot(np.asarray(train_sides)[nearest].ravel(), n).reshape(len(test), k, n).sum(axis=1)
    return probabilities(counts, smoothing)


def neighbour_forecast(train_states, train_sides, test_states, test_sides, cfg, *, seed=0, draws=BOOTSTRAP, reference=None):
    """A k-nearest-neighbour forecast of the test tracks' sides from their release states, with
    no physics: trained on (train_states, train_sides) only (states (m, 6) true units, sides
    0..n-1), its features, k and smoothing the ones with the best leave-one-out log score on
    the training tracks, then scored on the test tracks (log skill over 1/n with a bootstrap
    interval over test tracks, calibration, most likely side right; ``reference``: another
    forecast's probabilities of the same test tracks, for the paired difference of log scores)."""
    n = cfg.die.sides
    centre = phase_centre(np.asarray(train_states)[:, 2], n)
    train, train_turns = folded_release(train_states, cfg, centre)
    test, test_turns = folded_release(test_states, cfg, centre)
    folded_sides = (np.asarray(train_sides) + train_turns) % n
    tried = []
    for columns in NEIGHBOUR_FEATURES:
        for k in (len(train) - 1 if k is None else k for k in NEIGHBOURS):
            for smoothing in NEIGHBOUR_SMOOTHING:
                loo = neighbour_probabilities(train[:, columns], folded_sides, train[:, columns], n, k, smoothing, exclude_self=True)
                tried.append((log_scores(loo, folded_sides), columns, k, smoothing))
    # the one-standard-error rule: of the choices whose leave-one-out score is within one
    # standard error (paired, over tracks) of the best, the smoothest (most neighbours, then
    # most pseudo-counts); the best alone would be picked partly for its luck
    top = max(tried, key=lambda row: row[0].mean())[0]
    near = [row for row in tried if top.mean() - row[0].mean() <= np.std(top - row[0]) / math.sqrt(len(top))]
    scores, columns, k, smoothing = max(near, key=lambda row: (row[2], row[3]))
    best_loo = float(scores.mean())
    folded = neighbour_probabilities(train[:, columns], folded_sides, test[:, columns], n, k, smoothing)
    # back to the test die's own side names: real side s is folded side s + m
    prob = folded[np.arange(len(test))[:, None], (np.arange(n)[None, :] + test_turns[:, None]) % n]
    observed = np.asarray(test_sides)
    references = (("reference", np.asarray(reference)),) if reference is not None else ()
    scores, _ = _scores(prob, observed, np.random.default_rng([seed, 3141]), draws, RELIABILITY_BINS, references)
    right = prob.argmax(axis=1) == observed
    boot = bootstrap_means(right[:, None], np.random.default_rng([seed, 3142]), draws)[:, 0]
    return {**scores, "share_correct_most_likely": _entry(right.mean(), boot), "n_tracks": int(len(observed)),
            "n_train": int(len(train)), "features": [STATE_COLUMNS[c] for c in columns], "k": int(k), "smoothing": float(smoothing),
            "train_leave_one_out_log_skill": best_loo + math.log(n), "probabilities": prob}
