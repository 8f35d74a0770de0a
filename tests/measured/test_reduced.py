"""The reduced (states eliminated) problem (dice_sweep.measured.reduced) against direct least squares.

Cross-validation, the bootstrap and the null simulations use per-segment quadratic forms
instead of per-row residuals; here they are checked against the plain computation: for each
fold, one Gauss-Newton step of the whole linear problem (parameters and every kept segment's
state) by ``numpy.linalg.lstsq``, then each held-out segment's state refitted by ``lstsq``.
"""

from pathlib import Path

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dice_sweep.config import default_config, load_config
from dice_sweep.measured import reduced
from dice_sweep.measured.blocks import Linearisation
from dice_sweep.measured.fit import Segments

ROOT = Path(__file__).resolve().parents[2]
NAMES = ["beta_normal", "beta_tangential"]
VALUES = {"beta_normal": 0.5, "beta_tangential": 0.0}  # far from the bounds: no clipping


class FakeSegments:
    """The attributes of ``fit.Segments`` the reduced problem reads, and its ``subset``."""

    def __init__(self, rng, tracks=12):
        sizes, track = [], []
        for t in range(tracks):
            for _ in range(rng.integers(1, 4)):
                sizes.append(int(rng.integers(8, 20)))
                track.append(t)
        self.tracks = tracks
        self._index(track, sizes)

    def _index(self, track, sizes):
        """Row and segment indices from each segment's track and row count (as fit.Segments)."""
        self.count = len(sizes)
        self.track = np.array(track)
        self.starts = np.concatenate([[0], np.cumsum(sizes)])
        self.segment_rows = np.repeat(np.arange(self.count), sizes)
        self.track_rows = self.track[self.segment_rows]
        self.track_starts = np.searchsorted(self.track_rows, np.arange(self.tracks + 1))
        self.track_segment_starts = np.searchsorted(self.track, np.arange(self.tracks + 1))
        rows = self.starts[-1]
        self.times, self.measured, self.predicted = np.zeros(rows), np.zeros((rows, 3)), np.zeros(rows, bool)
        self.guess = np.zeros((self.count, 6))
        if not hasattr(self, "frame_rows"):  # each row its own frame, unless shared (SharedFrameSegments)
            self.frame_rows, self.frames = np.arange(rows), int(rows)

    def subset(self, keep):
        return Segments.subset(self, keep)


@pytest.fixture
def problem():
    rng = np.random.default_rng(3)
    seg = FakeSegments(rng)
    rows = seg.starts[-1]
    lin = Linearisation(rng.normal(size=(rows, 3)) * 1e-3, rng.uniform(0.2, 1.0, rows),
                                 rng.normal(size=(rows, 3, 2)), rng.normal(size=(rows, 3, 6)))
    fold = np.arange(seg.tracks) % 4
    return seg, lin, fold


def _direct_step(seg, lin, kept, residual):
    """One Gauss-Newton step of the whole linear problem of the segments ``kept`` (their rows,
    the parameters and every kept segment's state) by weighted ``lstsq``: (rows, joint step)."""
    sw = np.sqrt(lin.weight)
    rows = np.flatnonzero(np.isin(seg.segment_rows, kept))
    design = np.zeros((rows.size * 3, 2 + 6 * kept.size))
    design[:, :2] = (lin.jac_params[rows] * sw[rows, None, None]).reshape(-1, 2)
    column = {s: 2 + 6 * i for i, s in enumerate(kept)}
    for i, r in enumerate(rows):
        c = column[seg.segment_rows[r]]
        design[3 * i:3 * i + 3, c:c + 6] = lin.jac_states[r] * sw[r]
    target = -(residual[rows] * sw[rows, None]).reshape(-1)
    return rows, design, np.linalg.lstsq(design, target, rcond=None)[0]


def _direct_cv(seg, lin, fold, residual):
    """Held-out per-track RMS errors by direct weighted least squares."""
    sw = np.sqrt(lin.weight)
    errors = np.zeros(seg.tracks)
    for k in np.unique(fold):
        step = _direct_step(seg, lin, np.flatnonzero(fold[seg.track] != k), residual)[2][:2]
        for s in np.flatnonzero(fold[seg.track] == k):
            r = np.arange(seg.starts[s], seg.starts[s + 1])
            moved = residual[r] + lin.jac_params[r] @ step
            ds = np.linalg.lstsq((lin.jac_states[r] * sw[r, None, None]).reshape(-1, 6), -(moved * sw[r, None]).reshape(-1), rcond=None)[0]
            moved = moved + lin.jac_states[r] @ ds
            errors[seg.track[s]] += np.sum(moved**2)
    return np.sqrt(errors / np.diff(seg.track_starts))


def test_cross_validation_equals_direct_least_squares(problem):
    seg, lin, fold = problem
    cfg = load_config(ROOT / "configs" / "square_drops.toml")
    red = reduced.reduce(lin, seg)
    got = reduced.cv_errors(red, seg, fold, NAMES, VALUES, cfg, reduced.project(red, seg, centre=False))
    want = _direct_cv(seg, lin, fold, lin.residual)
    np.testing.assert_allclose(got, want, rtol=1e-6)


def test_a_batch_of_residuals_equals_one_at_a_time(problem):
    seg, lin, fold = problem
    cfg = load_config(ROOT / "configs" / "square_drops.toml")
    unit = np.ones_like(lin.weight)
    red = reduced.reduce(lin, seg, weight=unit)
    noise = np.random.default_rng(4).normal(size=lin.residual.shape + (5,)) * 1e-4
    batch = reduced.cv_errors(red, seg, fold, NAMES, VALUES, cfg, reduced.project(red, seg, noise, centre=False))
    for s in range(noise.shape[2]):
        one = reduced.cv_errors(red, seg, fold, NAMES, VALUES, cfg, reduced.project(red, seg, noise[:, :, s], centre=False))
        np.testing.assert_allclose(batch[:, s], one, rtol=1e-10)
        unit_lin = Linearisation(lin.residual, unit, lin.jac_params, lin.jac_states)
        np.testing.assert_allclose(one, _direct_cv(seg, unit_lin, fold, noise[:, :, s]), rtol=1e-6)


def test_bootstrap_without_resampling_is_the_full_step(problem):
    """With every track drawn once, a bootstrap draw is the one-step fit of all tracks: the
    centred gradient makes it the point itself."""
    seg, lin, fold = problem
    cfg = load_config(ROOT / "configs" / "square_drops.toml")
    red = reduced.reduce(lin, seg)

    class Once:
        def integers(self, low, high, size):
            return np.arange(size)

    draws = reduced.bootstrap_params(red, seg, NAMES, VALUES, cfg, Once(), draws=3)
    np.testing.assert_allclose(draws, [[0.5, 0.0]] * 3, atol=1e-12)


class SharedFrameSegments(FakeSegments):
    """Segments built like ``fit.Segments``: each flight's segment holds its own frames and the
    next flight's (the prediction through the impact), so those frames are rows twice."""

    def __init__(self, rng, tracks=8):
        frame_rows, track, frames = [], [], 0
        for t in range(tracks):
            own = [int(rng.integers(6, 12)) for _ in range(rng.integers(1, 4))]
            first = np.concatenate([[0], np.cumsum(own)]) + frames
            for k in range(len(own)):
                end = first[k + 2] if k + 1 < len(own) else first[k + 1]
                frame_rows.append(np.arange(first[k], end))
                track.append(t)
            frames = first[-1]
        self.tracks, self.frames = tracks, int(frames)
        self.frame_rows = np.concatenate(frame_rows)
        self._index(track, [rows.size for rows in frame_rows])


def test_noise_covariance_equals_direct_least_squares():
    """The parameters' covariance from frame noise against the weighted least-squares step of
    the whole linear problem (parameters and every segment's state), written as a matrix of the
    frames' noise: a frame measured by two segments moves both (rows drawn independently gave
    a covariance too small; the refits of docs/dev/measured_intervals.md share frames)."""
    rng = np.random.default_rng(7)
    seg = SharedFrameSegments(rng)
    rows = seg.starts[-1]
    lin = Linearisation(rng.normal(size=(rows, 3)) * 1e-3, rng.uniform(0.2, 1.0, rows),
                                 rng.normal(size=(rows, 3, 2)), rng.normal(size=(rows, 3, 6)))
    sigmas = np.array([2e-4, 3e-4, 1e-4])
    got = reduced.noise_covariance(reduced.reduce(lin, seg), seg, sigmas)
    design = np.zeros((rows * 3, 2 + 6 * seg.count))
    design[:, :2] = lin.jac_params.reshape(-1, 2)
    for r in range(rows):
        c = 2 + 6 * seg.segment_rows[r]
        design[3 * r:3 * r + 3, c:c + 6] = lin.jac_states[r]
    weight = np.repeat(lin.weight, 3)
    frames_to_rows = np.zeros((rows * 3, seg.frames * 3))  # the noise of frame f, column c lands on every row of f
    for r, f in enumerate(seg.frame_rows):
        frames_to_rows[3 * r:3 * r + 3, 3 * f:3 * f + 3] = np.eye(3)
    step = -np.linalg.solve(design.T @ (weight[:, None] * design), design.T @ (weight[:, None] * frames_to_rows))[:2]
    want = step @ np.diag(np.tile(sigmas**2, seg.frames)) @ step.T
    np.testing.assert_allclose(got, want, rtol=1e-6)
    # the same rows, each its own frame, give another covariance: the shared frames count
    seg.frame_rows, seg.frames = np.arange(rows), int(rows)
    apart = reduced.noise_covariance(reduced.reduce(lin, seg), seg, sigmas)
    assert np.max(np.abs(np.diag(apart) / np.diag(got) - 1.0)) > 0.05


# --- a parameter no track's residual moves with ----------------------------------------------------


def fit_of(names, values):
    return SimpleNamespace(free=tuple(names), params=dict(zip(names, values)), at_bound={})


def test_a_parameter_without_information_has_no_interval_and_excludes_nothing():
    """On the real drops the flat_landing candidate stayed at its start value (a contact time
    shorter than every landing's delay), its bootstrap interval had zero width, [3e-5, 3e-5] s,
    and the report called its null value excluded."""
    cfg = default_config()
    names = ["beta_normal", "contact_time"]
    fit = fit_of(names, [0.4, 3e-5])
    draws = np.column_stack([np.linspace(0.39, 0.41, 100), np.full(100, 3e-5)])  # zero width
    info = np.zeros((5, 2, 2))
    info[:, 0, 0] = 1.0  # each of 5 tracks informs beta_normal, none contact_time
    out = reduced.describe_params(fit, draws, cfg, SimpleNamespace(M=info))
    assert out["beta_normal"]["identified"] and out["beta_normal"]["ci95"][0] < 0.4 < out["beta_normal"]["ci95"][1]
    assert not out["contact_time"]["identified"]
    assert all(math.isnan(v) for v in out["contact_time"]["ci95"])
    assert not reduced.null_excluded("contact_time", out["contact_time"]["ci95"], cfg)
    # nor a zero-width interval from the tracks, nor a noise share, with the noise covariance
    out = reduced.describe_params(fit, draws, cfg, SimpleNamespace(M=info), noise_cov=np.diag([1e-6, 0.0]))
    assert all(math.isnan(v) for v in out["contact_time"]["ci95"] + out["contact_time"]["ci95_tracks"])
    assert math.isnan(out["contact_time"]["sd_noise"])
    assert out["beta_normal"]["ci95"][0] <= 0.4 - 1.96e-3 and out["beta_normal"]["ci95"][1] >= 0.4 + 1.96e-3  # spans the noise share
    # with any information the interval is kept and can exclude the null
    info[2, 1, 1] = 1e-3
    out = reduced.describe_params(fit, draws, cfg, SimpleNamespace(M=info))
    assert out["contact_time"]["identified"] and reduced.null_excluded("contact_time", out["contact_time"]["ci95"], cfg)


def test_a_part_step_is_the_parts_own_least_squares_step(problem):
    """Issue 30's consistency test fits each side of a split by one Newton step of its reduced
    problem (reduced.part_step): at an optimum of all tracks it is the direct least-squares step
    of the kept segments' rows alone, their states refitted."""
    seg, lin, _ = problem
    cfg = load_config(ROOT / "configs" / "square_drops.toml")
    rows, design, step = _direct_step(seg, lin, np.arange(seg.count), lin.residual)
    # the residual that is left at the optimum of all tracks: orthogonal to every column
    sw = np.sqrt(lin.weight)[rows, None]
    optimum = Linearisation(lin.residual + (design @ step).reshape(-1, 3) / sw, lin.weight, lin.jac_params, lin.jac_states)
    red = reduced.reduce(optimum, seg)
    keep = np.arange(seg.count) % 3 == 0
    values, _, part = reduced.part_step(red, seg, keep, NAMES, VALUES, cfg)
    want = _direct_step(seg, optimum, np.flatnonzero(keep), optimum.residual)[2][:2]
    assert want[0] != pytest.approx(0.0, abs=1e-6)  # the part has a step of its own to take
    np.testing.assert_allclose([values[n] - VALUES[n] for n in NAMES], want, rtol=1e-6, atol=1e-12)
    assert part.count == keep.sum() and part.tracks == np.unique(seg.track[keep]).size
    # all segments kept: the fit on all tracks itself, also with a gradient left (a rough cost)
    whole, _, _ = reduced.part_step(reduced.reduce(lin, seg), seg, np.ones(seg.count, bool), NAMES, VALUES, cfg)
    np.testing.assert_allclose([whole[n] for n in NAMES], [VALUES[n] for n in NAMES], atol=1e-12)
