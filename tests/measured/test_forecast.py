"""Tests of dice_sweep.measured.forecast, side forecasts of tracked drops (issue 18): the scores
against hand-computed values; the forecast's calibration and skill on drops from the independent
generator (a separate integrator: the kernel does not make the data), where the truth is known;
a diagnose report read as a fit. `dice-sweep forecast` end to end: tests/app/test_forecast.py."""

import math

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.geometry import side_below
from dice_sweep.measured import forecast as fc
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_RIGID, TRUTH
from tests.measured.independent import Truth, simulate_drops, simulate_path, write_csv



# --- scores against hand-computed values ---------------------------------------------------------


def test_probabilities_add_half_a_member_to_every_side():
    assert np.allclose(fc.probabilities([[3, 1, 0, 0]]), [[3.5 / 6, 1.5 / 6, 0.5 / 6, 0.5 / 6]])


def test_log_and_brier_scores_by_hand():
    prob = np.array([[0.5, 0.25, 0.125, 0.125], [0.25, 0.25, 0.25, 0.25]])
    assert np.allclose(fc.log_scores(prob, [1, 3]), [math.log(0.25), math.log(0.25)])
    # (0.5 - 1)^2 + 0.25^2 + 2 x 0.125^2 = 0.34375; uniform: 0.75^2 + 3 x 0.25^2 = 0.75 = (n - 1) / n
    assert np.allclose(fc.brier_scores(prob, [0, 2]), [0.34375, 0.75])
    assert fc.brier_scores([[1.0, 0.0, 0.0, 0.0]], [1])[0] == 2.0  # sure and wrong


def test_deterministic_forecast_is_an_ensemble_of_identical_members():
    prob = fc.deterministic_probabilities([2, -1], 4, members=1000)
    assert np.allclose(prob[0], [0.5 / 1002, 0.5 / 1002, 1000.5 / 1002, 0.5 / 1002])
    assert np.allclose(prob[1], 0.25)  # no side: uniform


def test_reliability_bins_by_hand():
    # pairs (p, happened): (0.9, 1), (0.1, 0), (0.2, 1), (0.8, 0)
    bins = fc.reliability([[0.9, 0.1], [0.2, 0.8]], [0, 0])
    assert [b["pairs"] for b in bins] == [0, 1, 1, 0, 0, 0, 0, 0, 1, 1]
    assert bins[9]["observed_frequency"] == 1.0 and bins[8]["observed_frequency"] == 0.0
    assert bins[2]["mean_predicted"] == pytest.approx(0.2)
    # Wilson interval of 1 in 1: ((1 + z^2/2) -+ z sqrt(z^2/4)) / (1 + z^2)
    z = fc.Z95
    assert bins[9]["ci95"] == pytest.approx([(1 + z * z / 2 - z * z / 2) / (1 + z * z), 1.0])
    assert bins[9]["calibrated_sd"] == pytest.approx(math.sqrt(0.9 * 0.1))


def test_calibration_test_by_hand():
    # two tracks of two sides: (0.8, 0.2) with side 0 and (0.5, 0.5) with side 1
    prob = np.array([[0.8, 0.2], [0.5, 0.5]])
    out = fc.calibration_test(prob, [0, 1])
    e1 = 0.8 * math.log(0.8) + 0.2 * math.log(0.2)
    v1 = 0.8 * math.log(0.8) ** 2 + 0.2 * math.log(0.2) ** 2 - e1**2
    expected = (math.log(0.8) - e1 + 0.0) / math.sqrt(v1 + 0.0)
    assert out["expected_log_score"] == pytest.approx((e1 + math.log(0.5)) / 2)
    assert out["log_score_z"] == pytest.approx(expected)
    # Brier: expectation 1 - sum p^2, variance 4 (sum p^3 - (sum p^2)^2)
    b_got = [(0.8 - 1) ** 2 + 0.2**2, 0.5]
    b_exp = [1 - 0.68, 1 - 0.5]
    b_var = [4 * (0.512 + 0.008 - 0.68**2), 0.0]
    assert out["expected_brier"] == pytest.approx(np.mean(b_exp))
    assert out["brier_z"] == pytest.approx(-(sum(b_got) - sum(b_exp)) / math.sqrt(sum(b_var)))


def test_blend_weight_by_hand():
    # a sure forecast right on half the tracks, n = 4: the mean log score
    # 0.5 ln(1 - 3w/4) + 0.5 ln(w/4) is largest at w = 2/3
    prob = np.tile([1.0, 0.0, 0.0, 0.0], (10, 1))
    observed = [0] * 5 + [1] * 5
    w = fc.fit_blend(prob, observed)
    assert w == pytest.approx(2 / 3, abs=1e-4)
    assert np.allclose(fc.blend(prob[:1], w), [[0.5, 1 / 6, 1 / 6, 1 / 6]], atol=1e-4)


def test_score_bounce_intervals_and_skills():
    rng = np.random.default_rng(0)
    tracks, n = 60, 4
    observed = rng.integers(0, n, tracks)
    counts = np.zeros((tracks, n), int)
    counts[np.arange(tracks), observed] = 900  # a good forecast
    counts += 25
    flight = fc.FlightState(1, np.zeros(6), np.eye(6), 1.0, 10, 0.0)
    bounce = fc.BounceForecast(0, np.arange(tracks), observed, counts, np.zeros(tracks, int), np.zeros(tracks, int), observed.copy(),
                               [flight] * tracks, 0)
    s = fc.score_bounce(bounce, n, rng)
    expected = math.log((925.5) / (1000 + 2))
    assert s["log_score"]["value"] == pytest.approx(expected)
    assert s["log_score"]["ci95"][0] <= s["log_score"]["value"] <= s["log_score"]["ci95"][1]
    assert s["log_score_uniform"]["value"] == pytest.approx(-math.log(4))
    assert s["brier_uniform"]["value"] == pytest.approx(0.75)
    assert s["log_skill"]["value"] == pytest.approx(expected + math.log(4))
    assert s["share_correct_deterministic"]["value"] == 1.0 and s["share_correct_most_likely"]["value"] == 1.0
    assert len(s["tracks"]) == tracks and s["tracks"][0]["probabilities"][observed[0]] == pytest.approx(925.5 / 1002)


def test_folding_the_angle_renames_the_sides():
    phi = np.random.default_rng(1).uniform(-10, 10, 200)
    folded, turns = fc.fold_phase(phi, 4, 0.3)
    assert np.all(np.abs(folded - 0.3) <= math.pi / 4 + 1e-12)
    assert np.array_equal(side_below(4, folded), (side_below(4, phi) + turns) % 4)


def test_map_axes_are_the_initial_values_that_vary_most():
    cfg = parse_config(DECLARED_RIGID)
    rng = np.random.default_rng(2)
    states = np.column_stack([rng.normal(0, 0.1, 300), rng.normal(0.15, 1e-3, 300), rng.uniform(-3, 3, 300),
                              rng.normal(-0.5, 0.01, 300), rng.normal(-2, 0.01, 300), rng.normal(0, 8, 300)])
    assert fc.choose_map_axes(states, cfg) == ("omega0", "phi0")  # x0 changes nothing without walls
    low, high = fc.map_range(states[:, 2], "phi0", cfg)
    assert high - low == pytest.approx(math.pi / 2)


# --- calibration and skill on independent synthetic drops ----------------------------------------

RIGID = parse_config(DECLARED_RIGID)
FRICTIONLESS = parse_config(DECLARED_RIGID.replace("friction = 0.5\n", ""))


def true_side(truth, state0, duration):
    """The side the independent generator's die rests on: once its energy
    (v^2/2 + I omega^2/2 + g y, per unit mass) is below g R no corner can pass under the centre
    again, and the side below the centre is final (docs/physics.md, outcome rule); None when
    the generator stopped before that (it does not simulate sustained contact)."""
    path = simulate_path(truth, state0, duration, min_bounce_speed=1e-4)
    x, y, phi, vx, vy, omega = path.centre_state(path.t_end)
    n, radius = truth.sides, truth.circumradius
    inertia = radius**2 * (math.sin(math.pi / n) ** 2 / 6 + math.cos(math.pi / n) ** 2 / 2)
    if 0.5 * (vx * vx + vy * vy) + 0.5 * inertia * omega * omega + truth.g * y >= truth.g * radius:
        return None
    return int(math.floor(((-math.pi / 2 - phi) % (2 * math.pi)) / (2 * math.pi / n))) % n


def synthetic(tmp_path_factory, name, truth, count, seed, noise, rate, **ranges):
    """Tracks of ``count`` drops from the independent generator and their true resting sides."""
    drops = simulate_drops(truth, count, seed, rate=rate, duration=3.0, noise=noise, **ranges)
    path = tmp_path_factory.mktemp(name) / "drops.csv"
    write_csv(path, drops)
    tracks = load_tracks(path, sides=truth.sides, circumradius=truth.circumradius)
    return tracks, {d["traj"]: true_side(truth, d["state0"], 3.0) for d in drops}


def known(params):
    """A fit that knows the truth: its parameters, no parameter uncertainty."""
    return fc.FitSource("truth", "fit", (), params, tuple(params), None, np.zeros(len(params)), "the truth", 0.3, 0, None, None)


def forecast(tracks, cfg, params, noise, observed, members=500):
    sigma = (noise[0], noise[0], noise[1])
    out, _, _ = fc.forecast_tracks(tracks.tracks, cfg, known(params), sigma=sigma, bounces=(0,), members=members, workers=2,
                                   observed=observed)
    return fc.score_bounce(out[0], 4, np.random.default_rng(0))


NOISY = (2e-3, 4e-2)  # a poor tracker: the release state is uncertain enough for probabilities between 0 and 1
HIGH = dict(height=(0.3, 0.4), vy=(-1.0, 0.0), spin=(-30.0, 30.0))


@pytest.fixture(scope="module")
def spread_drops(tmp_path_factory):
    return synthetic(tmp_path_factory, "spread", Truth(**TRUTH), 200, 1, NOISY, 250.0, **HIGH)


def test_forecast_is_calibrated_within_sampling_error(spread_drops):
    tracks, observed = spread_drops
    assert sum(side is not None for side in observed.values()) >= 140
    s = forecast(tracks, RIGID, dict(TRUTH_PARAMS), NOISY, observed)
    assert s["n_tracks"] >= 140
    assert 0.3 < s["mean_entropy"] < 1.0  # neither sure nor uniform: the test has power
    assert abs(s["calibration"]["log_score_z"]) < 3 and abs(s["calibration"]["brier_z"]) < 3
    for b in s["reliability"]:  # each well-filled bin within 3 binomial standard deviations
        if b["pairs"] >= 30:
            assert abs(b["observed_frequency"] - b["mean_predicted"]) < 3 * b["calibrated_sd"] + 0.02, b
    assert s["log_skill"]["ci95"][0] > 0.5


def test_a_wrong_model_fails_the_calibration_test(spread_drops):
    tracks, observed = spread_drops
    s = forecast(tracks, RIGID, {**TRUTH_PARAMS, "beta_normal": 0.3}, NOISY, observed)
    assert s["calibration"]["log_score_z"] < -5  # overconfident: sure of sides that did not happen
    assert s["log_score"]["ci95"][1] < s["calibration"]["expected_log_score"] - 1.0


TRUTH_PARAMS = {"beta_normal": TRUTH["beta_normal"], "beta_tangential": TRUTH["beta_tangential"], "friction": TRUTH["friction"]}


def test_skill_is_high_where_the_map_is_smooth(tmp_path_factory):
    """Low drops with little spin: the die lands and tips to the side below it."""
    tracks, observed = synthetic(tmp_path_factory, "smooth", Truth(**TRUTH), 100, 2, (2e-4, 4e-3), 500.0,
                                 height=(0.06, 0.07), vy=(-0.3, 0.0), vx=(-0.1, 0.1), spin=(-2.0, 2.0))
    s = forecast(tracks, RIGID, dict(TRUTH_PARAMS), (2e-4, 4e-3), observed)
    assert s["n_tracks"] >= 60
    assert s["log_skill"]["ci95"][0] > 1.0  # of at most ln 4 = 1.386
    assert s["share_correct_most_likely"]["value"] > 0.95


def test_skill_is_near_zero_where_the_map_is_fractal(tmp_path_factory):
    """High, fast-spinning drops of a lively die: a state known to micrometres still gives 1/n."""
    truth = Truth(contact="rigid", beta_normal=0.8, beta_tangential=0.0, friction=math.inf)
    tracks, observed = synthetic(tmp_path_factory, "fractal", truth, 90, 3, (2e-4, 4e-3), 500.0, **HIGH)
    s = forecast(tracks, FRICTIONLESS, {"beta_normal": 0.8, "beta_tangential": 0.0}, (2e-4, 4e-3), observed)
    assert s["n_tracks"] >= 70
    assert s["mean_entropy"] > 0.97 * math.log(4)
    assert abs(s["log_skill"]["value"]) < 0.06 and s["log_skill"]["ci95"][1] < 0.1
    assert abs(s["brier_skill"]["value"]) < 0.05


def test_a_diagnose_report_is_a_fit_too():
    cfg = parse_config(DECLARED_RIGID)
    params = {name: {"value": value, "ci95": [value - 0.01, value + 0.01]} for name, value in TRUTH_PARAMS.items()}
    report = {"after": {"params": params, "effects": ["corner_impulse", "coulomb_friction"]}, "effects_added": [],
              "data": {"path": "/x/drops.csv"}, "split": {"confirm_fraction": 0.25, "seed": 3}}
    source = fc.parse_fit(report, "r.json", cfg, 0.3, 0)
    assert source.kind == "diagnose" and source.params == TRUTH_PARAMS and source.draws is None
    assert (source.confirm_fraction, source.seed, source.data_path) == (0.25, 3, "/x/drops.csv")
    draws = fc.sample_params(source, cfg, 2000, np.random.default_rng(0))
    sd = np.std([d["beta_normal"] for d in draws])
    assert sd == pytest.approx(0.01 / fc.Z95, rel=0.1)


# --- the stochastic impact law in the ensemble (issue 31) -----------------------------------------

SCATTER = 0.08  # the truth's per-impact relative spread, both kinds
PRECISE = (5e-5, 1e-3)  # a tracker as good as the real one: without the law the ensemble is overconfident


def scattered_source(params, spreads):
    return fc.FitSource("truth", "fit", (), params, tuple(params), None, np.zeros(len(params)), "the truth", 0.3, 0, None, None,
                        spreads)


@pytest.fixture(scope="module")
def scattered_drops(tmp_path_factory):
    truth = Truth(**TRUTH, scatter_corner=SCATTER, scatter_flat=SCATTER, scatter_seed=5)
    return synthetic(tmp_path_factory, "scattered", truth, 160, 5, PRECISE, 500.0)


def scattered_forecast(tracks, observed, spreads):
    sigma = (PRECISE[0], PRECISE[0], PRECISE[1])
    out, _, _ = fc.forecast_tracks(tracks.tracks, RIGID, scattered_source(dict(TRUTH_PARAMS), spreads), sigma=sigma, bounces=(0,),
                                   members=500, workers=2, observed=observed)
    return fc.score_bounce(out[0], 4, np.random.default_rng(0))


def test_the_stochastic_law_calibrates_the_forecast_of_scattering_drops(scattered_drops):
    """Drops whose bounces scatter: the ensemble drawn from the true stochastic law is
    calibrated (|z| < 3, reliability within binomial bands); without the law it is not."""
    tracks, observed = scattered_drops
    s = scattered_forecast(tracks, observed, {"corner": SCATTER, "flat": SCATTER})
    assert s["n_tracks"] >= 100
    assert abs(s["calibration"]["log_score_z"]) < 3 and abs(s["calibration"]["brier_z"]) < 3, s["calibration"]
    for b in s["reliability"]:
        if b["pairs"] >= 30:
            assert abs(b["observed_frequency"] - b["mean_predicted"]) < 3 * b["calibrated_sd"] + 0.02, b
    exact = scattered_forecast(tracks, observed, None)
    assert exact["calibration"]["log_score_z"] < -5  # the same drops forecast by the exact law: overconfident
    assert fc.headline(s)[0].startswith("ensemble (calibrated)")


def test_warnings_name_forecasts_below_uniform_and_parameters_at_a_bound():
    scores = {"from_bounce": 0, "log_skill": {"value": 0.1}, "log_skill_deterministic": {"value": -2.0},
              "recalibrated": {"log_skill": {"value": 0.02}}}
    source = scattered_source({"beta_normal": 1.0, "beta_tangential": 0.0, "friction": 0.5}, None)
    lines = fc.warnings({**scores, "by_bounce": [scores]}, source, RIGID)
    assert len(lines) == 2
    assert "deterministic from flight 0" in lines[0] and "ensemble" not in lines[0]
    assert "beta_normal = 1 at its upper bound" in lines[1]
    quiet = scattered_source({"beta_normal": 0.4, "beta_tangential": 0.0, "friction": 0.5}, None)
    assert fc.warnings({"by_bounce": [{**scores, "log_skill_deterministic": {"value": 0.5}}]}, quiet, RIGID) == []


# --- one scale of the law, chosen by the forecasts' log score (issue 31) ---------------------------


def scale_of(tracks, observed, spreads):
    sigma = (PRECISE[0], PRECISE[0], PRECISE[1])
    source = scattered_source(dict(TRUTH_PARAMS), spreads)
    prepared = fc.prepared_tracks(tracks.tracks, RIGID, sigma, 0.0, observed)
    return fc.fit_scatter_scale(prepared, RIGID, source, (0, 1), sigma=sigma, observed=observed, members=200, workers=2)


@pytest.mark.slow
def test_the_scale_of_the_law_is_found_by_the_forecasts_log_score(scattered_drops, tmp_path_factory):
    """Drops whose bounces scatter by 0.08: a law given at half that is scaled by about 2 (the
    interval covers 2, not 1); the true law (the control, nothing to find) keeps an interval
    holding 1; forecasts of other drops, from the release and from flight 1, with the scaled
    half law are calibrated (|z| < 3)."""
    tracks, observed = scattered_drops
    half = {"corner": SCATTER / 2, "flat": SCATTER / 2}
    found = scale_of(tracks, observed, half)
    assert found["ci95"][0] <= 2.0 <= found["ci95"][1] and found["ci95"][0] > 1.2, found
    assert not found["at_grid_end"] and found["pairs"] > 150
    control = scale_of(tracks, observed, {"corner": SCATTER, "flat": SCATTER})
    assert control["ci95"][0] <= 1.0 <= control["ci95"][1], control
    truth = Truth(**TRUTH, scatter_corner=SCATTER, scatter_flat=SCATTER, scatter_seed=6)
    other, seen = synthetic(tmp_path_factory, "scattered_other", truth, 160, 6, PRECISE, 500.0)
    sigma = (PRECISE[0], PRECISE[0], PRECISE[1])
    scaled = scattered_source(dict(TRUTH_PARAMS), fc.scaled_scatter(half, found["value"]))
    out, _, _ = fc.forecast_tracks(other.tracks, RIGID, scaled, sigma=sigma, bounces=(0, 1), members=500, workers=2, observed=seen)
    for k in (0, 1):
        s = fc.score_bounce(out[k], 4, np.random.default_rng(0))
        assert s["n_tracks"] >= 90
        assert abs(s["calibration"]["log_score_z"]) < 3 and abs(s["calibration"]["brier_z"]) < 3, (k, s["calibration"])
    unscaled = scattered_source(dict(TRUTH_PARAMS), half)
    out, _, _ = fc.forecast_tracks(other.tracks, RIGID, unscaled, sigma=sigma, bounces=(0, 1), members=500, workers=2, observed=seen)
    assert min(fc.score_bounce(out[k], 4, np.random.default_rng(0))["calibration"]["log_score_z"] for k in (0, 1)) < -3  # the test has power


# --- the model-free forecast from the release (k nearest neighbours) -----------------------------


def _release_drops(count, seed, informative):
    """Release states and sides from a rule written here (no package code): the die turned by m
    quarter turns rests on the side m lower (geometry's convention), and within a quarter turn
    the side is set by the sign of the spin, 80 % of the time (``informative``), else by a coin."""
    rng = np.random.default_rng(seed)
    period = math.pi / 2
    phi = rng.uniform(-3.0, 3.0, count)
    omega = rng.uniform(-10.0, 10.0, count)
    states = np.column_stack([rng.normal(0, 0.01, count), rng.uniform(0.1, 0.2, count), phi, rng.normal(0, 0.3, count),
                              rng.normal(-2.0, 0.2, count), omega])
    turns = np.floor((phi + 0.25 * math.pi) / period).astype(int)
    base = np.where(omega > 0, 0, 2)
    sides = np.where(rng.random(count) < 0.8, base, rng.integers(0, 4, count)) if informative else rng.integers(0, 4, count)
    return states, (sides - turns) % 4


@pytest.mark.parametrize("informative", [True, False])
def test_the_model_free_forecast_finds_what_the_release_tells_and_nothing_else(informative):
    """Trained on 400 drops, scored on 300 others: with sides set by the spin the skill's
    interval is above 0 and its most likely side is right far above 1/4; the control (sides
    from a die nobody threw) claims no skill: its interval reaches 0 or below (a learner fitted
    to noise may score below the uniform forecast: here -0.049 [-0.078, -0.020], the training
    tracks' chance imbalance of sides, 124 of 400 on one, not shared by the test tracks)."""
    cfg = parse_config("[die]\nsides = 4\n")
    train, train_sides = _release_drops(400, 1, informative)
    test, test_sides = _release_drops(300, 2, informative)
    got = fc.neighbour_forecast(train, train_sides, test, test_sides, cfg, draws=500)
    low, high = got["log_skill"]["ci95"]
    if informative:
        assert low > 0.2 and got["share_correct_most_likely"]["value"] > 0.6, got["log_skill"]
        assert "omega0" in got["features"]
    else:
        assert low <= 0.0 and got["log_skill"]["value"] < 0.02, got["log_skill"]
    assert got["n_tracks"] == 300 and got["n_train"] == 400


def test_the_model_free_forecast_pairs_with_a_reference():
    """The paired difference against a reference forecast of the same tracks: the uniform one's
    log score is -ln 4, so the difference is the skill itself."""
    cfg = parse_config("[die]\nsides = 4\n")
    train, train_sides = _release_drops(200, 3, True)
    test, test_sides = _release_drops(100, 4, True)
    got = fc.neighbour_forecast(train, train_sides, test, test_sides, cfg, draws=200, reference=np.full((100, 4), 0.25))
    assert got["log_skill_over_reference"]["value"] == pytest.approx(got["log_skill"]["value"])


# --- the law's form: a scatter growing faster than the approach speed (issue 31) -----------------


@pytest.mark.slow
def test_a_law_whose_power_is_estimated_forecasts_calibrated(tmp_path_factory):
    """Drops whose bounces scatter with sd 0.02 sqrt(gR) (u / sqrt(gR))^2 and a floor of 0.03
    sqrt(gR): the law estimated from 120 of them (impact residuals, the power free) has a power
    interval holding 2 and not 1, and a scale (chosen by those drops' forecasts) holding 1;
    forecasts of 160 other drops from the release and from flights 1 and 2 with it are
    calibrated (|z| < 3). By hand (the same calls, load 8): power 2.0 [1.8, 2.2], scale 0.96
    [0.78, 1.13]; z log -0.0, 0.8, 1.4. The old form (power held at 1, its own scale 1.17 [0.85,
    1.39]) gave -0.7, 2.1, 1.9: also within 3 on drops this few, so this does not show it fail."""
    from dice_sweep.measured.scatter import estimate_spreads, impact_residuals

    truth = Truth(**TRUTH, scatter_corner=0.02, scatter_flat=0.02, scatter_floor=0.03, scatter_power=2.0, scatter_seed=7)
    selection, seen = synthetic(tmp_path_factory, "power_selection", truth, 120, 7, PRECISE, 500.0)
    other, other_seen = synthetic(tmp_path_factory, "power_other", truth, 160, 8, PRECISE, 500.0)
    sigma = (PRECISE[0], PRECISE[0], PRECISE[1])
    residuals = impact_residuals(selection.tracks, RIGID, (), TRUTH_PARAMS, sigma=sigma, seed=7)
    got = estimate_spreads(residuals, speed=math.sqrt(9.81 * RIGID.die.circumradius), seed=7)
    low, high = got["power"]["ci95"]
    assert low <= 2.0 <= high and low > 1.0, got["power"]
    law = {"corner": got["corner"]["value"], "corner_floor": got["corner"]["floor"], "flat": got["flat"]["value"],
           "flat_floor": got["flat"]["floor"], "power": got["power"]["value"]}
    prepared = fc.prepared_tracks(selection.tracks, RIGID, sigma, 0.0, seen)
    scale = fc.fit_scatter_scale(prepared, RIGID, scattered_source(dict(TRUTH_PARAMS), law), (0, 1, 2), sigma=sigma, observed=seen,
                                 members=200, workers=2)
    assert scale["ci95"][0] <= 1.0 <= scale["ci95"][1], scale
    source = scattered_source(dict(TRUTH_PARAMS), fc.scaled_scatter(law, scale["value"]))
    out, _, _ = fc.forecast_tracks(other.tracks, RIGID, source, sigma=sigma, bounces=(0, 1, 2), members=500, workers=2, observed=other_seen)
    for k in (0, 1, 2):
        s = fc.score_bounce(out[k], 4, np.random.default_rng(0))
        assert s["n_tracks"] >= 100
        assert abs(s["calibration"]["log_score_z"]) < 3 and abs(s["calibration"]["brier_z"]) < 3, (k, s["calibration"])
