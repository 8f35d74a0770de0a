"""The reduced problem of a fit, and the intervals of its parameters.

With each segment's state refitted to first order, a parameter step ``dp`` moves a row's
residual r to r~ + C dp, where r~ = r - B x (x = inv(Hss) gs: the states alone refitted) and
C = A - B X (X = inv(Hss) Hsp) the reduced Jacobian; A, B are the row's Jacobians in the
parameters and in its segment's state, H and g the weighted normal blocks. A track's squared
error after a step is then q + 2 dp.v + dp^T U dp, with q = sum |r~|^2, v = sum C^T r~ and
U = sum C^T C over its rows, all sums of per-segment blocks (:mod:`dice_sweep.measured.blocks`):
nothing per row is needed once the blocks are known, and everything is linear in r, so one
residual or a batch of simulated noise residuals (a trailing axis S) costs a product per
segment.

On it the loop refits folds (cross-validation over tracks), resamples tracks (the one-step
bootstrap) and propagates the tracking noise, each a linear solve instead of a refit; the
parameters' 95 % intervals come from the last two (:func:`parameter_intervals`).
"""

import math
from dataclasses import dataclass

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.measured.blocks import STATE, Linearisation, damped_inverse, segment_products, segment_sums
from dice_sweep.measured.stats import BOOTSTRAP, Z95


@dataclass
class Reduced:
    """The residual-independent pieces of a fit's reduced problem."""

    lin: Linearisation
    weight: np.ndarray  # (rows,) the weights of the refits
    hss_inv: np.ndarray  # (segments, 6, 6) weighted
    solved: np.ndarray  # (segments, 6, p): X
    plain: tuple  # unweighted (hss, hsp) per segment: errors are unweighted RMS
    M: np.ndarray  # (tracks, p, p): weighted reduced normal matrix (the refits)
    U: np.ndarray  # (tracks, p, p): unweighted sum of C^T C (the errors)


@dataclass
class Projected:
    """A residual (or a batch) on the reduced problem, per track: ``q`` (tracks, ...), ``v`` and
    ``b`` (the weighted gradient of the refits), (tracks, p, ...)."""

    q: np.ndarray
    v: np.ndarray
    b: np.ndarray


def _by_track(values, segments):
    """Sums over each track's segments (segments are grouped by track) -> (tracks, ...)."""
    return segment_sums(values, segments.track_segment_starts)


def reduce(lin, segments, weight=None):
    """The reduced pieces of a linearisation (weights default to the fit's)."""
    weight = lin.weight if weight is None else weight
    jac = lin.joint_jacobian()
    unit = np.ones_like(weight)
    hessian, _ = segment_products(jac, weight, lin.residual, segments.starts)
    plain = hessian if np.array_equal(weight, unit) else segment_products(jac, unit, lin.residual, segments.starts)[0]
    hss, hsp, hpp = hessian[:, :STATE, :STATE], hessian[:, :STATE, STATE:], hessian[:, STATE:, STATE:]
    inv = damped_inverse(hss, 0.0)
    X = inv @ hsp
    M = _by_track(hpp - hsp.transpose(0, 2, 1) @ X, segments)
    uss, usp, upp = plain[:, :STATE, :STATE], plain[:, :STATE, STATE:], plain[:, STATE:, STATE:]
    cross = usp.transpose(0, 2, 1) @ X
    U = _by_track(upp - cross - cross.transpose(0, 2, 1) + X.transpose(0, 2, 1) @ uss @ X, segments)
    return Reduced(lin, weight, inv, X, (uss, usp), M, U)


def project(red, segments, residual=None, centre=True):
    """A residual (rows, 3) or a batch (rows, 3, S), default the fit's own, on the reduced
    problem (:class:`Projected`)."""
    residual = red.lin.residual if residual is None else residual
    single = residual.ndim == 2
    residual = residual[:, :, None] if single else residual
    jac = red.lin.joint_jacobian()
    unit = np.ones_like(red.weight)
    _, grad_w = segment_products(jac, red.weight, residual, segments.starts, hessian=False)
    if np.array_equal(red.weight, unit):
        grad_u = grad_w
    else:
        _, grad_u = segment_products(jac, unit, residual, segments.starts, hessian=False)
    rr = segment_sums(np.sum(residual * residual, axis=1), segments.starts)  # (segments, S)
    uss, usp = red.plain
    Xt = red.solved.transpose(0, 2, 1)
    x = red.hss_inv @ grad_w[:, :STATE]  # (segments, 6, S): the states' refit
    b = grad_w[:, STATE:] - Xt @ grad_w[:, :STATE]
    gs_u, gp_u = grad_u[:, :STATE], grad_u[:, STATE:]
    q = rr - 2.0 * np.sum(x * gs_u, axis=1) + np.sum(x * (uss @ x), axis=1)
    v = gp_u - usp.transpose(0, 2, 1) @ x - Xt @ gs_u + Xt @ (uss @ x)
    q, v, b = _by_track(q, segments), _by_track(v, segments), _by_track(b, segments)
    if centre:
        # the fit is taken as the optimum: what is left of the gradient (a bound, a rough
        # cost) is spread evenly, so refits and resamples move only by the tracks they drop
        b = b - b.mean(axis=0)
    if single:
        q, v, b = q[:, 0], v[:, :, 0], b[:, :, 0]
    return Projected(q, v, b)


def _solve(M, b):
    """-(M)^-1 b with a small ridge for directions the tracks do not pin (b: (p,) or (p, S))."""
    p = M.shape[0]
    if p == 0:
        return np.zeros(b.shape)
    ridge = 1e-9 * max(float(np.trace(M)) / p, 1e-30)
    return -np.linalg.solve(M + ridge * np.eye(p), b)


def _clip_step(values, names, step, cfg):
    """Step on the parameters (p,) or (p, S) kept inside their bounds."""
    base = np.array([values[n] for n in names], dtype=float).reshape((-1,) + (1,) * (np.ndim(step) - 1))
    bounds = np.array([registry.param(n).bounds_of(cfg) for n in names], dtype=float).reshape((-1, 2) + (1,) * (np.ndim(step) - 1))
    return np.clip(base + step, bounds[:, 0], bounds[:, 1]) - base


def cv_errors(red, segments, fold, names, values, cfg, projected=None):
    """Per-track held-out RMS errors (m), (tracks,) or (tracks, S) for a batch of residuals:
    K-fold over tracks, each fold's refit one Newton step of the reduced problem, the held-out
    tracks' states refitted to first order. ``projected``: from :func:`project`, default the
    fit's own residual."""
    pr = project(red, segments) if projected is None else projected
    e2 = np.array(pr.q, dtype=float)
    for k in np.unique(fold):
        keep = fold != k
        step = _clip_step(values, names, _solve(red.M[keep].sum(axis=0), pr.b[keep].sum(axis=0)), cfg)  # (p, ...)
        held = fold == k
        e2[held] += 2.0 * np.einsum("tp...,p...->t...", pr.v[held], step) + np.einsum("p...,tpr,r...->t...", step, red.U[held], step)
    counts = np.diff(segments.track_starts).reshape((-1,) + (1,) * (e2.ndim - 1))
    return np.sqrt(np.maximum(e2, 0.0) / np.maximum(counts, 1))


def part_reduced(red, segments, keep):
    """The reduced problem of the segments where ``keep`` (bool per segment) holds, cut from
    ``red`` of all ``segments`` (each segment's blocks are its own: its state is eliminated
    alone), with those segments (:meth:`~dice_sweep.measured.fit.Segments.subset`)."""
    keep = np.asarray(keep, dtype=bool)
    rows = keep[segments.segment_rows]
    lin = red.lin
    part = segments.subset(keep)
    cut = Linearisation(lin.residual[rows], lin.weight[rows], lin.jac_params[rows], lin.jac_states[rows])
    return reduce(cut, part), part


def part_step(red, segments, keep, names, values, cfg):
    """A part's values of the parameters ``names``: one Newton step of its reduced problem from
    the fit on all tracks (``values``; the estimator of the bootstrap and of the re-splits).
    What is left of the gradient on all tracks (a rough cost, a bound) is taken off in
    proportion to the part's segments, as :func:`project` spreads it. Returns (values, the
    part's reduced problem, its segments)."""
    red_part, part = part_reduced(red, segments, keep)
    if not names:
        return dict(values), red_part, part
    left = project(red, segments, centre=False).b.sum(axis=0)
    b = project(red_part, part, centre=False).b.sum(axis=0) - left * (part.count / segments.count)
    step = _clip_step(values, names, _solve(red_part.M.sum(axis=0), b), cfg)
    return dict(values, **{n: float(values[n] + step[k]) for k, n in enumerate(names)}), red_part, part


def bootstrap_params(red, segments, names, values, cfg, rng, draws=BOOTSTRAP):
    """One-step bootstrap over tracks: (draws, p) parameter values."""
    b = project(red, segments).b
    tracks, p = b.shape
    counts = np.stack([np.bincount(rng.integers(0, tracks, tracks), minlength=tracks) for _ in range(draws)]).astype(float)
    if p == 0:
        return np.zeros((draws, 0))
    M = np.einsum("dt,tij->dij", counts, red.M)
    ridge = 1e-9 * np.maximum(np.einsum("dii->d", M) / p, 1e-30)
    step = -np.linalg.solve(M + ridge[:, None, None] * np.eye(p), (counts @ b)[:, :, None])[:, :, 0]
    step = _clip_step(values, names, step.T, cfg).T
    return np.array([values[n] for n in names]) + step


def noise_covariance(red, segments, sigmas):
    """(p, p) covariance of the parameters from the tracking noise alone, to first order: each
    frame's noise (``sigmas`` of x, y and R phi, m) moves the reduced gradient through every row
    that measures the frame (its flight's segment and the one before, which predicts it), and a
    step is -M^-1 times that gradient.

    Why beside the bootstrap over tracks: on 48 sets from the independent generator the
    bootstrap's friction intervals covered the truth 41 times, 43 with this beside them
    (scripts/coverage_measured.py, docs/dev/measured_intervals.md)."""
    lin = red.lin
    p = lin.jac_params.shape[2]
    if p == 0:
        return np.zeros((0, 0))
    # C = A - B X per row: the parameters' Jacobian with the row's segment state refitted
    reduced_jac = lin.jac_params - lin.jac_states @ red.solved[segments.segment_rows]
    per_frame = np.zeros((segments.frames, 3, p))
    np.add.at(per_frame, segments.frame_rows, reduced_jac * red.weight[:, None, None])
    per_frame *= np.asarray(sigmas, dtype=float)[None, :, None]
    gradient_cov = np.einsum("fcp,fcq->pq", per_frame, per_frame)
    inverse = _solve(red.M.sum(axis=0), -np.eye(p))
    return inverse @ gradient_cov @ inverse.T


def bootstrap_record(names, draws):
    """A fit's bootstrap draws for its JSON (``bootstrap_draws``: ``forecast`` samples the
    parameters from them, issue 18)."""
    return {"names": list(names), "values": np.asarray(draws, dtype=float).reshape(-1, len(names)).tolist(),
            "method": "one-step bootstrap over the selection tracks (docs/measured_method.md), one row per resample"}


def null_excluded(name, interval, cfg):
    """Whether a 95 % interval excludes a parameter's null value (a null at infinity, as for
    friction, is excluded when the interval stays below the upper fit bound)."""
    entry = registry.param(name)
    null = entry.null_value(cfg)
    if not all(math.isfinite(v) for v in interval):
        return False  # no interval (a parameter the tracks say nothing about) excludes nothing
    if math.isinf(null):
        return interval[1] < entry.bounds_of(cfg)[1] * (1 - 1e-6)
    return not (interval[0] <= null <= interval[1])


def effect_away_from_null(effect_name, params, cfg):
    """Whether an effect's 95 % intervals (``params`` as :func:`describe_params` gives them)
    put it away from its null: for a vector effect (com_offset) one component is enough; an
    effect without parameters (a switch, corner_impulse) always is."""
    own = [p.name for p in registry.effect(effect_name).params]
    return not own or any(null_excluded(n, params[n]["ci95"], cfg) for n in own)


TOP_TRACK_SHARE = 0.5  # a parameter whose information comes this much from one track is flagged


def describe_params(fit, draws, cfg, red=None, noise_cov=None):
    """Value, 95 % interval, unit, bound and null of each fitted parameter; with ``red``, the
    share of its information (diagonal of the reduced normal matrix) from the most informative
    track, flagged above TOP_TRACK_SHARE: one track then decides the value (seen when a
    prediction passes near a discontinuity) and the interval is not to be trusted; a parameter
    with no information at all gets no interval (NaN) and ``identified`` false.

    The interval (``ci95``) spans both the bootstrap over tracks (``ci95_tracks``: what differs
    from track to track, model error included) and, with ``noise_cov`` (:func:`noise_covariance`),
    value +- 1.96 sd of the tracking noise's share (``sd_noise``), kept inside the fit bounds: on
    the independent generator's drops the bootstrap alone was too narrow for friction
    (docs/dev/measured_intervals.md)."""
    out = {}
    for k, name in enumerate(fit.free):
        entry = registry.param(name)
        value = float(fit.params[name])
        tracks = [float(np.quantile(draws[:, k], 0.025)), float(np.quantile(draws[:, k], 0.975))] if draws is not None else [math.nan, math.nan]
        interval = list(tracks)
        out[name] = {"value": value, "ci95": interval, "ci95_tracks": tracks, "unit": entry.unit,
                     "at_bound": fit.at_bound.get(name, False), "null": entry.null_value(cfg)}
        if noise_cov is not None:
            sd = float(math.sqrt(max(noise_cov[k, k], 0.0)))
            low, high = entry.bounds_of(cfg)
            out[name]["sd_noise"] = sd
            out[name]["ci95"] = [max(min(tracks[0], value - Z95 * sd), low), min(max(tracks[1], value + Z95 * sd), high)]
        if red is not None:
            info = red.M[:, k, k]
            share = float(info.max() / info.sum()) if info.sum() > 0 else math.nan
            out[name]["top_track_share"] = share
            out[name]["one_track_decides"] = bool(share > TOP_TRACK_SHARE)
            # No track's residual moves with it (e.g. a contact time shorter than every
            # landing's delay): the bootstrap would give a zero-width interval, not a measurement.
            out[name]["identified"] = bool(info.sum() > 0)
            if not out[name]["identified"]:
                out[name]["ci95"] = out[name]["ci95_tracks"] = [math.nan, math.nan]
                out[name]["sd_noise"] = math.nan
    return out


def parameter_intervals(fit, red, segments, cfg, rng, sigmas, draws=BOOTSTRAP):
    """A fit's bootstrap draws over tracks and its described parameters (:func:`describe_params`
    with the noise covariance for ``sigmas`` of x, y and R phi, m)."""
    values = bootstrap_params(red, segments, list(fit.free), fit.params, cfg, rng, draws)
    return values, describe_params(fit, values, cfg, red, noise_covariance(red, segments, sigmas))

