"""Multiple shooting on drops from the independent generator with (almost) no tracking noise:
the fit must find the true coefficients, not a nearby optimum where flights sit in the wrong
basin (a bounce that goes another way)."""

import numpy as np
import pytest

from dice_sweep import effects as registry
from dice_sweep.config import parse_config
from dice_sweep.measured import fit as shooting
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_RIGID, RADIUS, TRUE_COEFFICIENTS
from tests.measured.independent import Truth, simulate_drops, write_csv

NOISE = (1e-6, 2e-5)  # m, rad: far below anything the coefficients change


@pytest.fixture(scope="module")
def segments(tmp_path_factory):
    path = tmp_path_factory.mktemp("exact") / "drops.csv"
    write_csv(path, simulate_drops(Truth(contact="rigid", **TRUE_COEFFICIENTS), 60, 100, rate=500.0, noise=NOISE,
                                   drop_prob=0.0, glitch_prob=0.0))
    cfg = parse_config(DECLARED_RIGID)
    prepared = shooting.prepare_tracks(load_tracks(path, sides=4, circumradius=RADIUS), cfg, noise=np.array([NOISE[0], NOISE[0], NOISE[1]]))
    return cfg, shooting.Segments(prepared, cfg.world.g)


def test_fit_from_the_config_finds_the_true_coefficients(segments):
    """Caught: from the config's values (beta_normal 0.3, friction 0.5) the fit stopped at friction
    0.295 with a cost 3e5 times the truth's; the fresh states after convergence fix it."""
    cfg, seg = segments
    fit = shooting.fit_spec(cfg, shooting.ModelSpec.of(cfg), seg)
    for name, true in TRUE_COEFFICIENTS.items():
        assert fit.params[name] == pytest.approx(true, abs=1e-3), name
    truth = shooting.fit_spec(cfg, shooting.ModelSpec.of(cfg), seg, start=TRUE_COEFFICIENTS, fixed=True)
    assert fit.cost <= 1.01 * truth.cost


def test_every_flight_is_described_to_the_noise_at_the_truth(segments):
    """The kernel and the independent generator agree: with the true coefficients and fitted
    states, no flight's RMS error exceeds a few times the noise."""
    cfg, seg = segments
    truth = shooting.fit_spec(cfg, shooting.ModelSpec.of(cfg), seg, start=TRUE_COEFFICIENTS, fixed=True)
    residual = shooting.ShootingModel(cfg, truth.spec, seg).residuals(truth.params, truth.states)
    e2 = np.einsum("ij,ij->i", residual, residual)
    per_flight = np.sqrt(np.add.reduceat(e2, seg.starts[:-1]) / np.diff(seg.starts))
    assert per_flight.max() < 2e-5  # m; the pose noise is about 2e-6 m


def test_frame_rows_point_at_the_frames_each_row_measures(segments):
    cfg, seg = segments
    assert seg.frame_rows.size == seg.measured.shape[0] and seg.frame_rows.max() < seg.frames
    # a flight's frames are rows of its own segment and of the one before (the prediction)
    counts = np.bincount(seg.frame_rows, minlength=seg.frames)
    assert counts.max() == 2 and (counts == 2).sum() > 0
    same = seg.frame_rows[:, None] == seg.frame_rows[None, :200]
    rows, cols = np.nonzero(same)
    np.testing.assert_array_equal(seg.measured[rows], seg.measured[cols])


def test_the_noise_covariance_matches_refits_of_simulated_noise(tmp_path):
    """First-order noise sd (reduced.noise_covariance) against the spread of warm refits of the
    fitted model's poses with tracking noise added, one draw per frame: the nonlinear fit, not
    the linear algebra (tests/measured/test_reduced.py does that). 30 refits: the spread's own
    uncertainty is about 13 %."""
    from dice_sweep.measured import reduced
    from tests.measured.cases import NOISE as TRACKER

    path = tmp_path / "drops.csv"
    write_csv(path, simulate_drops(Truth(contact="rigid", **TRUE_COEFFICIENTS), 40, 7, rate=500.0, noise=TRACKER))
    cfg = parse_config(DECLARED_RIGID)
    sigma = np.array([TRACKER[0], TRACKER[0], TRACKER[1]])
    seg = shooting.Segments(shooting.prepare_tracks(load_tracks(path, sides=4, circumradius=RADIUS), cfg, noise=sigma), cfg.world.g)
    spec = shooting.ModelSpec.of(cfg)
    fit = shooting.fit_spec(cfg, spec, seg)
    red = reduced.reduce(shooting.linearise(cfg, fit, seg), seg)
    first_order = np.sqrt(np.diag(reduced.noise_covariance(red, seg, (sigma[0], sigma[1], RADIUS * sigma[2]))))
    clean, _ = shooting.ShootingModel(cfg, spec, seg).simulate(fit.params, fit.states)
    rng = np.random.default_rng(1)
    refits = []
    for _ in range(30):
        seg.measured = clean + (rng.normal(size=(seg.frames, 3)) * sigma)[seg.frame_rows]
        refit = shooting.fit_spec(cfg, spec, seg, start=fit.params, states=fit.states)
        refits.append([refit.params[name] for name in fit.free])
    ratio = np.std(refits, axis=0) / first_order
    print("refit sd / first-order sd:", {name: round(float(r), 2) for name, r in zip(fit.free, ratio)})  # docs/measured_method.md quotes these (-s)
    assert np.all((ratio > 0.7) & (ratio < 1.4)), dict(zip(fit.free, ratio))


def test_the_fits_coarser_drag_steps_move_no_residual_by_a_nanometre(segments, monkeypatch):
    """The fit runs drag at FIT_DRAG_TOL and FIT_DRAG_MAX_STEP (3x faster on the real drops);
    on every row of the independent generator's drops, at drag 0.5 1/m, the residuals stay
    within 1e-9 m of the kernel's default steps, and the fit's values do reach the kernel."""
    from dice_sweep.physics import params as kernel_params

    cfg, seg = segments
    spec = shooting.ModelSpec.of(cfg).with_effect("air_drag")
    values = {**TRUE_COEFFICIENTS, "air_drag": 0.5}
    model = shooting.ShootingModel(cfg, spec, seg)
    seen = []
    kernel = shooting.sample_batch
    monkeypatch.setattr(shooting, "sample_batch", lambda fpar, *rest: (seen.append(fpar.copy()), kernel(fpar, *rest)))
    coarse = model.residuals(values, seg.guess)
    assert seen[-1][kernel_params.FP_DRAG_TOL] == shooting.FIT_DRAG_TOL
    assert seen[-1][kernel_params.FP_DRAG_MAX_STEP] == shooting.FIT_DRAG_MAX_STEP
    monkeypatch.setattr(shooting, "FIT_DRAG_TOL", kernel_params.DRAG_TOL)
    monkeypatch.setattr(shooting, "FIT_DRAG_MAX_STEP", kernel_params.DRAG_MAX_STEP)
    fine = model.residuals(values, seg.guess)
    assert np.abs(coarse - fine).max() < 1e-9


def test_a_parameter_the_frames_hardly_see_does_not_freeze_the_fit(tmp_path):
    """Caught on hexagons at 1000 Hz: with beta_tangential 0, friction 0.5 caps no impulse, its
    curvature was 1e-19 of beta_normal's, Marquardt damping let finite-difference noise send it
    1e5 out, every trial was clipped to its bound and worse, and the fit stopped at its start
    values as converged. With the curvature floored (PARAM_DAMPING_FLOOR) it moves off them."""
    radius = 0.025
    truth = Truth(sides=6, circumradius=radius, contact="rigid", beta_normal=0.4, beta_tangential=0.0, friction=0.3)
    path = tmp_path / "hexagon.csv"
    write_csv(path, simulate_drops(truth, 60, 119, rate=1000.0, noise=NOISE))
    cfg = parse_config(DECLARED_RIGID.replace("sides = 4", "sides = 6").replace(f"circumradius = {RADIUS!r}", f"circumradius = {radius!r}"))
    prepared = shooting.prepare_tracks(load_tracks(path, sides=6, circumradius=radius), cfg, noise=np.array([NOISE[0], NOISE[0], NOISE[1]]))
    seg = shooting.Segments(prepared, cfg.world.g)
    start = shooting.start_values(cfg, shooting.ModelSpec.of(cfg))
    fit = shooting.fit_spec(cfg, shooting.ModelSpec.of(cfg), seg)
    assert fit.params["beta_normal"] > start["beta_normal"] + 0.05  # 0.384 (truth 0.4; a local optimum, see docs)
    # (This test also refitted with the floor at 0 and asserted that the fit froze at its start.
    # Whether it freezes is a matter of finite-difference round-off: on the 2-core machine of
    # 2026-11-27 the unfloored fit reached beta_normal 0.400 at 3e2d2a0 too, and the test failed
    # there. What the floor does is pinned by the next test instead.)


def test_the_damping_floor_lifts_a_curvature_the_frames_hardly_see():
    """Friction 0.5 capping no impulse had a curvature 1e-19 of beta_normal's; the floor makes
    it at least PARAM_DAMPING_FLOOR of the largest, in registry scales, so that Marquardt
    damping bounds its step."""
    scales = np.array([0.1, 0.1])
    hpp = np.diag([2.0e4, 2.0e-15])
    floor = shooting.damping_floor(hpp, scales)
    largest = 2.0e4 * 0.1**2
    assert floor == pytest.approx(np.full(2, shooting.PARAM_DAMPING_FLOOR * largest) / scales**2, rel=1e-12)
    assert floor[1] > 1e8 * hpp[1, 1]  # the unseen parameter's step is bounded by the floor, not by its curvature
    assert shooting.damping_floor(np.zeros((0, 0)), np.zeros(0)).size == 0


def test_the_damping_floor_is_a_share_of_the_largest_scaled_curvature():
    hpp = np.diag([4.0, 1e-19, 2.0])
    scales = np.array([0.1, 0.1, 1e-3])
    floor = shooting.damping_floor(hpp, scales)
    largest = max(4.0 * 0.1**2, 2.0 * 1e-6)  # beta-like 0.04 beats the third's 2e-6
    assert floor == pytest.approx(shooting.PARAM_DAMPING_FLOOR * largest / scales**2)
    assert shooting.damping_floor(np.zeros((0, 0)), np.zeros(0)).size == 0


def _packed_config(model, values, t_max):
    """The kernel's vectors the way the fit made them before it wrote values into slots: a
    config rebuilt with the values set (kernel_config), packed, with the fit's settings."""
    from dice_sweep.physics import pack_params
    from dice_sweep.physics.params import FP_DRAG_MAX_STEP, FP_DRAG_TOL, IP_CONTINUE

    fpar, ipar = pack_params(shooting.kernel_config(model.cfg, model.spec, values, t_max=t_max))
    fpar[FP_DRAG_TOL] = shooting.FIT_DRAG_TOL
    fpar[FP_DRAG_MAX_STEP] = shooting.FIT_DRAG_MAX_STEP
    ipar[IP_CONTINUE] = 1
    return fpar, ipar


@pytest.mark.parametrize("effect", [None, *registry.names()])
def test_values_written_into_slots_give_the_residuals_of_a_rebuilt_config(segments, effect, monkeypatch):
    """Every fittable parameter, moved a quarter of its fit range from its start: the vectors
    equal those of the config rebuilt and packed, bit for bit, and so do the residuals (issue 29)."""
    cfg, seg = segments
    spec = shooting.ModelSpec.of(cfg, () if effect is None else (effect,))
    model = shooting.ShootingModel(cfg, spec, seg)
    own = [p.name for p in (registry.BASE_PARAMS if effect is None else registry.effect(effect).params)]
    values = shooting.start_values(cfg, spec)
    for name in own:
        low, high = registry.param(name).bounds_of(cfg)
        step = 0.25 * (high - low)
        values[name] += step if values[name] + step <= high else -step
    new_fpar, new_ipar = model.kernel_params(values, 0.7)
    old_fpar, old_ipar = _packed_config(model, values, 0.7)
    np.testing.assert_array_equal(new_fpar, old_fpar)
    np.testing.assert_array_equal(new_ipar, old_ipar)
    new = model.residuals(values, seg.guess)
    monkeypatch.setattr(model, "kernel_params", lambda values, t_max: _packed_config(model, values, t_max))
    old = model.residuals(values, seg.guess)
    np.testing.assert_allclose(new, old, rtol=1e-12, atol=0)
    assert not np.array_equal(new, model.residuals(shooting.start_values(cfg, spec), seg.guess)) or not own  # the values count
