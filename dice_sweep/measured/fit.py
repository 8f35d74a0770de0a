"""Fitting the model to whole tracked drops by multiple shooting.

Every free flight of a track (found by :func:`dice_sweep.measured.flights.find_flights`) is a
*segment* with its own state (x, y, phi, vx, vy, omega at its first frame, in the file's units).
A segment is simulated by the kernel from that state over its own flight and on through the
next impact over the next flight, so each frame of a bounce is described twice: as the flight a
state was fitted to, and as the prediction of the impact before it. The states of all segments
and the model's parameters (the declared model's beta_normal and beta_tangential plus the
parameters of the effects tried, from the registry in :mod:`dice_sweep.effects`) are fitted
jointly: flight effects (drag, g, a loaded die) act on the flights the states are fitted to,
so they are fitted consistently, and every bounce counts.

The fit is a Levenberg-Marquardt least squares with a soft-L1 loss (scale ``ROBUST_SCALE`` R,
iteratively reweighted), finite-difference Jacobians in batches of the kernel (one batch per
state component and per parameter), and the segments' states eliminated block by block (a
Schur complement), so a step costs a few kernel batches whatever the number of tracks.

Measurement effects (kind "measurement" in the registry: the tracker's clock, length scale,
angle zero and height zero) act between the simulation and the tracks: states are kept in the
file's units, mapped to true units for the kernel, and its poses mapped back to what the
tracker would report.

The error of a track is the RMS over its described frames of sqrt(dx^2 + dy^2 + (R dphi)^2)
(m). Tracks are the independent units.
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.blocks import Linearisation, damped_inverse, normal_blocks, segment_sums
from dice_sweep.measured.flights import segment_track
from dice_sweep.physics.kernel import sample_batch
from dice_sweep.physics.layout import PATH_CUT, SAMPLE_RECORDS
from dice_sweep.physics.params import FP_DRAG_MAX_STEP, FP_DRAG_TOL, FP_TMAX, IP_CONTINUE, KeyWriter

MIN_FLIGHT_FRAMES = 4  # a flight needs this many usable frames to carry a state of its own
ROBUST_SCALE = 0.05  # R: soft-L1 scale; larger misfits (a bounce that went another way) count less
MAX_ITERATIONS = 40
TOLERANCE = 1e-6  # relative fall of the cost below which the fit has converged
# forward-difference steps of a segment state (file units: m, m, rad, m/s, m/s, rad/s)
STATE_STEPS = np.array([1e-7, 1e-7, 1e-6, 1e-6, 1e-6, 1e-5])
PARAM_STEP = 1e-4  # of a parameter's typical size (registry ``scale``)
# A finite-difference step moves a smooth prediction by micrometres at most; a prediction that
# moves more than this (R) crossed a discontinuity (another corner hit first): its derivative
# is not a derivative, and the rows of that segment after the jump get none.
JUMP = 1e-3
MAX_FLIGHTS = 6  # flights per track: the first bounces; later ones are rocking on a corner
# Flight with drag: the kernel's defaults hold each Runge-Kutta step to 1e-13 rho_max, which a
# sweep needs and a fit to data noisy by ~1e-4 m does not. These moved the real drops' residuals
# by at most 3.5e-10 m at drag 0.05 and 0.5 1/m and made them 3.3 and 2.6 times faster: the
# air_drag candidate was the longest task of every round of diagnose (docs/dev/measured_speed.md).
FIT_DRAG_TOL = 1e-11  # x rho_max
FIT_DRAG_MAX_STEP = 5e-3  # s


@dataclass(frozen=True)
class ModelSpec:
    """The declared model plus added effects (names from the registry).

    The parameters of the declared effects are fitted too: a config declares which physics
    there is, the tracks say how much.
    """

    effects: tuple = ()
    declared: tuple = ()

    @classmethod
    def of(cls, cfg, effects=()):
        return cls(tuple(effects), registry.declared_effects(cfg))

    def param_names(self):
        on = self.declared + self.effects
        dropped = {d for name in on for d in registry.effect(name).drops}
        names = [p.name for p in registry.BASE_PARAMS if p.name not in dropped]
        for name in on:
            names += [p.name for p in registry.effect(name).params]
        return names

    def with_effect(self, name):
        return ModelSpec(self.effects + (name,), self.declared)

    def without(self, names):
        return ModelSpec(tuple(e for e in self.effects if e not in names), self.declared)


def declared_effects(cfg):
    return registry.declared_effects(cfg)


def start_values(cfg, spec):
    """The config's value of every parameter of the spec (an effect not declared starts at its
    null value, or at its first start value where the null is not a number, as for friction)."""
    values = {}
    for name in spec.param_names():
        entry = registry.param(name)
        value = float(registry.get_key(cfg, entry.key))
        if not math.isfinite(value):
            value = entry.starts_of(cfg)[0]
        low, high = entry.bounds_of(cfg)
        values[name] = min(max(value, low), high)
    return values


@dataclass(frozen=True)
class PreparedTrack:
    """A track cut into segments: its flights and the frames each segment describes."""

    traj: int
    t: np.ndarray  # s, file times of the usable frames
    pose: np.ndarray  # (frames, 3) x, y, phi as in the file (model convention)
    flights: tuple  # (first, last) indices into t of each flight
    t_impact: float  # s, file time of the first impact (end of the first flight), nan if none


def prepare_tracks(trackset, cfg, noise=None, table=0.0):
    """Usable frames and flights of each track (``noise``: sigma of x, y, phi, or None to
    estimate it per track; ``table``: the table's height in the file, m). Frames a flight's fit rejects as glitches are left out; tracks
    whose first flight is shorter than MIN_FLIGHT_FRAMES are left out (nothing gives them a
    state)."""
    sides, radius, g = cfg.die.sides, cfg.die.circumradius, cfg.world.g
    prepared = []
    for track in trackset.tracks:
        ok = track.usable
        if ok.sum() < MIN_FLIGHT_FRAMES:
            continue
        seg = segment_track(track.t, track.x, track.y, track.phi, ok, sides=sides, circumradius=radius, g=g, noise=noise, table=table)
        keep = ok & ~seg.outliers
        index = np.flatnonzero(keep)
        flights = []
        for first, last in seg.flights[:MAX_FLIGHTS]:
            inside = np.flatnonzero((index >= first) & (index <= last))
            if inside.size >= MIN_FLIGHT_FRAMES:
                flights.append((int(inside[0]), int(inside[-1])))
        if not flights:  # (frames before the first flight, such as a bad first frame, are left out)
            continue
        t = track.t[keep]
        pose = np.column_stack([track.x[keep], track.y[keep], track.phi[keep]])
        t_impact = float(t[flights[0][1]]) if len(flights) > 1 else math.nan
        prepared.append(PreparedTrack(track.traj, t, pose, tuple(flights), t_impact))
    return prepared


def _ballistic_guess(t, pose, g):
    """(x, y, phi, vx, vy, omega) at t[0] of a least-squares free flight through the frames."""
    dt = t - t[0]
    design = np.column_stack([np.ones_like(dt), dt])
    target = pose.copy()
    target[:, 1] += 0.5 * g * dt * dt
    (p0, v), *_ = np.linalg.lstsq(design, target, rcond=None)
    return np.array([p0[0], p0[1], p0[2], v[0], v[1], v[2]])


class Segments:
    """The segments of prepared tracks, flattened for the kernel.

    Attributes: ``track`` (segment -> track index), ``starts`` (row offsets per segment),
    ``times`` (file s from the segment's first frame), ``measured`` (rows, 3),
    ``predicted`` (row after the segment's impact), ``track_rows`` (row -> track),
    ``guess`` (segments, 6) ballistic start states in file units, ``frame_rows`` (row -> frame
    of the prepared tracks, numbered across tracks: a flight's frames are rows of its own segment
    and of the one before, which predicts them, so they carry the same tracking noise twice).
    """

    def __init__(self, prepared, g):
        track, times, measured, predicted, track_rows, guess, starts = [], [], [], [], [], [], [0]
        frame_rows, frames = [], 0
        for i, prep in enumerate(prepared):
            for k, (first, last) in enumerate(prep.flights):
                end = prep.flights[k + 1][1] if k + 1 < len(prep.flights) else last
                rows = np.arange(first, end + 1)
                track.append(i)
                times.append(prep.t[rows] - prep.t[first])
                measured.append(prep.pose[rows])
                predicted.append(rows > last)
                track_rows.append(np.full(rows.size, i))
                frame_rows.append(frames + rows)
                guess.append(_ballistic_guess(prep.t[first:last + 1], prep.pose[first:last + 1], g))
                starts.append(starts[-1] + rows.size)
            frames += prep.t.size
        self.count = len(track)
        self.tracks = len(prepared)
        self.track = np.array(track, dtype=np.int64)
        self.starts = np.array(starts, dtype=np.int64)
        self.times = np.concatenate(times) if times else np.zeros(0)
        self.measured = np.concatenate(measured) if measured else np.zeros((0, 3))
        self.predicted = np.concatenate(predicted) if predicted else np.zeros(0, bool)
        self.track_rows = np.concatenate(track_rows) if track_rows else np.zeros(0, np.int64)
        self.frame_rows = np.concatenate(frame_rows) if frame_rows else np.zeros(0, np.int64)
        self.frames = frames
        self.segment_rows = np.repeat(np.arange(self.count), np.diff(self.starts))
        # rows are grouped by track: each track's first row, and the end
        self.track_starts = np.searchsorted(self.track_rows, np.arange(self.tracks + 1))
        self.track_segment_starts = np.searchsorted(self.track, np.arange(self.tracks + 1))
        self.guess = np.array(guess).reshape(-1, 6)

    def subset(self, keep):
        """The segments where ``keep`` (bool, per segment) holds, as their own Segments: tracks
        with none kept are left out and the rest renumbered in order; ``frame_rows`` keep the
        frame numbering of the whole (cross-fitting and the consistency test fit parts of one
        set of tracks and put their states and residuals back in place)."""
        keep = np.asarray(keep, dtype=bool)
        out = object.__new__(Segments)
        rows = keep[self.segment_rows]
        kept_tracks = np.unique(self.track[keep])
        renumber = np.full(self.tracks, -1, dtype=np.int64)
        renumber[kept_tracks] = np.arange(kept_tracks.size)
        lengths = np.diff(self.starts)[keep]
        out.count = int(keep.sum())
        out.tracks = int(kept_tracks.size)
        out.track = renumber[self.track[keep]]
        out.starts = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        out.times = self.times[rows]
        out.measured = self.measured[rows]
        out.predicted = self.predicted[rows]
        out.track_rows = renumber[self.track_rows[rows]]
        out.frame_rows = self.frame_rows[rows]
        out.frames = self.frames
        out.segment_rows = np.repeat(np.arange(out.count), lengths)
        out.track_starts = np.searchsorted(out.track_rows, np.arange(out.tracks + 1))
        out.track_segment_starts = np.searchsorted(out.track, np.arange(out.tracks + 1))
        out.guess = self.guess[keep]
        return out


def _physical(values):
    """The ``values`` (name -> value) the kernel reads: measurement effects are maps of the
    poses, not the kernel's."""
    return {k: v for k, v in values.items() if registry.param(k).key.split(".")[0] != "tracking"}


def kernel_config(cfg, spec, values, **integrator):
    """The config the kernel runs at fitted ``values``: the spec's effects on, the physical
    parameters set, the event integrator; ``integrator`` overrides more of its keys (``t_max``)."""
    out = registry.with_values(cfg, spec.effects, _physical(values))
    return dataclasses.replace(out, integrator=dataclasses.replace(out.integrator, method="event", **integrator))


class ShootingModel:
    """Simulated poses of segments for a spec's parameters and the segments' states.

    The kernel's vectors are packed once, from the config with the spec's effects switched on;
    each evaluation writes the parameters' values straight into a copy of ``fpar`` through
    their registry slots (:class:`dice_sweep.physics.params.KeyWriter`), bit for bit the
    vectors of :func:`kernel_config` packed.
    """

    def __init__(self, cfg, spec, segments):
        self.cfg = cfg
        self.spec = spec
        self.seg = segments
        self.names = spec.param_names()
        self.radius = cfg.die.circumradius
        self.packed = KeyWriter(kernel_config(cfg, spec, {}))
        self.packed.fpar[FP_DRAG_TOL] = FIT_DRAG_TOL
        self.packed.fpar[FP_DRAG_MAX_STEP] = FIT_DRAG_MAX_STEP
        self.packed.ipar[IP_CONTINUE] = 1

    def kernel_params(self, values, t_max):
        """(fpar, ipar) of the kernel at ``values`` (name -> value) and time limit ``t_max`` (s)."""
        fpar = self.packed.fpar_with({registry.param(name).key: value for name, value in _physical(values).items()})
        fpar[FP_TMAX] = t_max
        return fpar, self.packed.ipar

    def simulate(self, values, states):
        """Poses (rows, 3) as the tracker would see them, and the outcome code per segment."""
        times_to_true, state_to_true, pose_to_file = registry.measurement_maps(self.cfg, values)
        times = times_to_true(self.seg.times)
        horizon = float(times.max()) if times.size else 0.0
        fpar, ipar = self.kernel_params(values, horizon + 1e-3)
        out = np.zeros((self.seg.times.size, 6))
        outcome = np.zeros(self.seg.count, np.int8)
        sample_batch(fpar, ipar, np.ascontiguousarray(state_to_true(states)), np.ascontiguousarray(times), self.seg.starts, out, outcome)
        if (outcome == PATH_CUT).any():
            raise DiceSweepError(f"fit: a segment's simulated path needs more than {SAMPLE_RECORDS} kernel records "
                                 "(allowed: segments between impacts of real drops need a few)")
        return pose_to_file(out[:, :3]), outcome

    def residuals(self, values, states):
        """(rows, 3) simulated minus measured, the angle times R (m)."""
        poses, _ = self.simulate(values, states)
        diff = poses - self.seg.measured
        diff[:, 2] *= self.radius
        return diff


def _robust_weights(residual, scale):
    """Soft-L1 IRLS weight per row: rho(e) = 2 c^2 (sqrt(1 + e^2/c^2) - 1), w = rho'(e)/(2e)."""
    e2 = np.einsum("ij,ij->i", residual, residual)
    return 1.0 / np.sqrt(1.0 + e2 / scale**2)


def _robust_loss(residual, scale):
    """Soft-L1 loss rho per row (see :func:`_robust_weights`)."""
    e2 = np.einsum("ij,ij->i", residual, residual)
    return 2.0 * scale**2 * (np.sqrt(1.0 + e2 / scale**2) - 1.0)


def _robust_cost(residual, scale):
    return float(np.sum(_robust_loss(residual, scale)))


def _difference(model, moved_residual, residual, step):
    """(moved - base) / step, with rows at or after a jump (JUMP R) in their segment zeroed."""
    delta = moved_residual - residual
    size = np.sqrt(np.einsum("ij,ij->i", delta, delta))
    jumped = size > JUMP * model.radius
    if jumped.any():
        # from the first jumping row of a segment on: a discontinuity is crossed once
        seg = model.seg.segment_rows
        first = np.full(model.seg.count, np.iinfo(np.int64).max)
        np.minimum.at(first, seg[jumped], np.flatnonzero(jumped))
        delta[np.arange(delta.shape[0]) >= first[seg]] = 0.0
    return delta / step


def _jacobians(model, values, states, residual, free_params):
    """Forward-difference Jacobians: (rows, 3, p) for ``free_params`` and (rows, 3, 6)."""
    rows = residual.shape[0]
    jac_states = np.zeros((rows, 3, 6))
    for c in range(6):
        moved = states.copy()
        moved[:, c] += STATE_STEPS[c]
        jac_states[:, :, c] = _difference(model, model.residuals(values, moved), residual, STATE_STEPS[c])
    jac_params = np.zeros((rows, 3, len(free_params)))
    for k, name in enumerate(free_params):
        entry = registry.param(name)
        step = PARAM_STEP * entry.scale
        low, high = entry.bounds_of(model.cfg)
        if values[name] + step > high:
            step = -step
        moved = dict(values)
        moved[name] = values[name] + step
        jac_params[:, :, k] = _difference(model, model.residuals(moved, states), residual, step)
    return jac_params, jac_states


@dataclass(frozen=True)
class FitResult:
    spec: ModelSpec
    params: dict  # name -> value (SI units of the registry)
    states: np.ndarray  # (segments, 6) file units
    free: tuple  # names of the fitted parameters
    cost: float  # robust cost at the solution
    iterations: int
    converged: bool
    at_bound: dict  # name -> bool


# Marquardt damping scales each parameter's step by its own curvature; a parameter the frames
# hardly see (friction 0.5 with beta_tangential 0: hardly an impulse reaches the cap, its curvature
# 1e-19 of beta_normal's) then took steps of 1e5 from finite-difference noise in its gradient,
# every trial was clipped to its bound and worse, and the fit stopped at its start values as
# "converged" (one of 20 hexagon sets at 1000 Hz of scripts/coverage_measured.py --sides 6;
# tests/measured/test_fit.py).
# Its curvature is floored at this share of the largest, in units of the registry's scales.
PARAM_DAMPING_FLOOR = 1e-6


def damping_floor(hpp, scales):
    """Least curvature (per parameter, its own units) that damps a parameter's step."""
    if not scales.size:
        return np.zeros(0)
    scaled = np.diag(hpp) * scales**2
    return np.maximum(PARAM_DAMPING_FLOOR * scaled.max(), 1e-30) / scales**2


def relative_gain(cost, new_cost):
    return (cost - new_cost) / max(cost, 1e-300)


def _fit(model, values, states, free, max_iterations=MAX_ITERATIONS):
    """Levenberg-Marquardt over ``free`` parameters and all states; returns (values, states,
    cost, iterations, converged)."""
    scale = ROBUST_SCALE * model.radius
    starts = model.seg.starts
    residual = model.residuals(values, states)
    cost = _robust_cost(residual, scale)
    damping = 1e-3
    converged = False
    iterations = 0
    small = 0
    restarted = False
    bounds = [registry.param(name).bounds_of(model.cfg) for name in free]
    scales = np.array([registry.param(name).scale for name in free])
    for iterations in range(1, max_iterations + 1):
        weight = _robust_weights(residual, scale)
        jac_p, jac_s = _jacobians(model, values, states, residual, free)
        lin = Linearisation(residual, weight, jac_p, jac_s)
        hss, hsp, hpp, gs, gp = normal_blocks(lin, starts)
        hpp_total = hpp.sum(axis=0)
        floor_p = damping_floor(hpp_total, scales)
        improved = False
        for _ in range(16):
            inv = damped_inverse(hss, damping)
            step_p = np.zeros(len(free))
            if free:
                solved = inv @ hsp  # (segments, 6, p)
                reduced = hpp_total - np.sum(hsp.transpose(0, 2, 1) @ solved, axis=0)
                grad = gp.sum(axis=0) - np.einsum("sjp,sj->p", solved, gs)
                diag = np.diag(reduced).copy()
                reduced = reduced + np.diag(damping * np.maximum(diag, floor_p) + 1e-30)
                step_p = -np.linalg.solve(reduced, grad)
            step_s = -(inv @ (gs + hsp @ step_p)[:, :, None])[:, :, 0]
            trial_values = dict(values)
            for k, name in enumerate(free):
                low, high = bounds[k]
                trial_values[name] = float(min(max(values[name] + step_p[k], low), high))
            trial_states = states + step_s
            trial_residual = model.residuals(trial_values, trial_states)
            trial_cost = _robust_cost(trial_residual, scale)
            if trial_cost < cost:
                improved = True
                relative = relative_gain(cost, trial_cost)
                values, states, residual, cost = trial_values, trial_states, trial_residual, trial_cost
                damping = max(damping / 3.0, 1e-7)
                break
            damping *= 4.0
        if improved and relative >= TOLERANCE:
            small, restarted = 0, False
            continue
        small += improved
        if restarted:
            # the fresh, lightly damped step went nowhere either: converged
            converged = True
            break
        if not improved or small >= 2:
            # two small gains (or none) are convergence only if a fresh, lightly damped step
            # agrees: the damping grows on a rough cost, and a small gain from a heavily damped
            # step once hid a candidate refit that went 40 % lower
            restarted, damping, small = True, 1e-3, 0
    return values, states, cost, iterations, converged


AT_BOUND = 1e-6  # share of a parameter's range within which it counts as at that bound
FRESH_PASSES = 2  # times the states are refitted from their ballistic guesses after a fit


def _segment_costs(model, values, states):
    residual = model.residuals(values, states)
    return segment_sums(_robust_loss(residual, ROBUST_SCALE * model.radius), model.seg.starts)


def _fresh_states(model, values, states):
    """Each segment's state refitted from its ballistic guess with the parameters held; a
    segment takes it where its cost is lower. Returns (states, how many changed).

    States fitted while the parameters were still far off can stay in the wrong basin (a bounce
    that goes another way, its rows' derivatives cut at the jump): on drops from the independent
    generator without noise, a fit from the config's values stopped at a cost 3e5 times the
    truth's, friction 0.295 for 0.3, with 288 of 417 flights in such basins; the same fit from
    fresh states found the truth (tests/measured/test_fit.py)."""
    _, fresh, _, _, _ = _fit(model, values, model.seg.guess.copy(), (), MAX_ITERATIONS)
    better = _segment_costs(model, values, fresh) < _segment_costs(model, values, states) * (1.0 - 1e-6)
    return np.where(better[:, None], fresh, states), int(better.sum())


def fit_spec(cfg, spec, segments, start=None, states=None, fixed=False, max_iterations=MAX_ITERATIONS, refresh=False):
    """Fit a spec's parameters (unless ``fixed``) and every segment's state.

    ``start`` (name -> value) overrides the config's start values; ``states`` the ballistic
    guesses. With ``fixed`` only the states are fitted (held-out tracks). A fit from the
    guesses refits each state from its guess at the fitted parameters once converged, and goes
    on (:func:`_fresh_states`, at most FRESH_PASSES times). With ``refresh`` given states are
    first compared, segment by segment, with a fit from the guesses at the start values: a
    candidate effect that changes how dice land (flat_landing) puts the flights after a
    landing in other basins than the current model's states, and a candidate fit from those
    stopped at 50 times the cost of the truth
    (tests/measured/test_diagnose.py::test_flat_landing_contact_time_is_found).
    """
    model = ShootingModel(cfg, spec, segments)
    values = start_values(cfg, spec)
    if start:
        values.update({k: v for k, v in start.items() if k in values})
    from_guesses = states is None
    states = segments.guess.copy() if from_guesses else states.copy()
    free = () if fixed else tuple(spec.param_names())
    if refresh and not from_guesses:
        states, _ = _fresh_states(model, values, states)
    values, states, cost, iterations, converged = _fit(model, values, states, free, max_iterations)
    # states fitted from their guesses while the parameters were far off: give each segment a
    # fresh start at the fitted parameters (a fit from given states, a candidate's, moves little)
    for _ in range(FRESH_PASSES if free and from_guesses else 0):
        fresh, changed = _fresh_states(model, values, states)
        if not changed:
            break
        values, states, cost, more, converged = _fit(model, values, fresh, free, max_iterations)
        iterations += more
    return FitResult(spec, values, states, free, cost, iterations, converged, at_bounds(cfg, values, free))


def at_bounds(cfg, values, names):
    """name -> whether its value lies within AT_BOUND of its range from a fit bound."""
    out = {}
    for name in names:
        low, high = registry.param(name).bounds_of(cfg)
        span = high - low
        out[name] = bool(values[name] <= low + AT_BOUND * span or values[name] >= high - AT_BOUND * span)
    return out


def linearise(cfg, fit, segments, free=None):
    """Jacobians and IRLS weights of a fit at its solution (``free``: parameters to include;
    default the fitted ones)."""
    model = ShootingModel(cfg, fit.spec, segments)
    free = fit.free if free is None else free
    residual = model.residuals(fit.params, fit.states)
    weight = _robust_weights(residual, ROBUST_SCALE * model.radius)
    jac_p, jac_s = _jacobians(model, fit.params, fit.states, residual, free)
    return Linearisation(residual, weight, jac_p, jac_s)


def track_errors(segments, residual):
    """RMS pose error (m) per track over the rows of its segments."""
    e2 = np.einsum("ij,ij->i", residual, residual)
    sums = np.bincount(segments.track_rows, e2, minlength=segments.tracks)
    counts = np.bincount(segments.track_rows, minlength=segments.tracks)
    with np.errstate(invalid="ignore"):
        return np.sqrt(sums / counts)


def rms(errors):
    errors = np.asarray(errors, dtype=float)
    errors = errors[np.isfinite(errors)]
    return float(np.sqrt(np.mean(np.square(errors)))) if errors.size else math.nan
