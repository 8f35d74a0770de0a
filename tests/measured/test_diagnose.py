"""The loop on tracked drops made by an independent simulator (tests/measured/independent.py,
which shares no code with the kernel): each library effect alone, none (several splits), two at
once, two effects outside the library, 4x the tracking noise, flat_landing on drops that
start near flat (its own starts, so not in LIBRARY_CASES), a loaded die under a friction rule
the config lacks, a second draw of the new contact physics naming the same effects, and (issue
30) the same verdict from two draws of the same physics, causes and stand-ins, and the JSON
contract of verdict_spread, cause and proposals.

The default suite runs a few of these (the control and a flight effect); all of them run with ``make test-measured``
(``pytest -m slow tests/measured``), minutes on two cores.
"""

import math

import pytest

from dice_sweep import effects as registry
from dice_sweep.config import parse_config
from dice_sweep.measured.diagnose import diagnose
from dice_sweep.measured.reduced import effect_away_from_null, null_excluded
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_PAPER, DECLARED_RIGID, NOISE, RADIUS, TRUTH
from tests.measured.independent import Truth, simulate_drops, write_csv

TRACKS = 90


def run_loop(tmp_path, truth, declared=DECLARED_RIGID, *, seed=1, noise=NOISE, tracks=TRACKS, split_seed=0, starts=None, **options):
    truth = dict(truth)
    table = truth.pop("table_offset", 0.0)  # the generator's table is at y = 0: the tracker's zero moved here
    drops = simulate_drops(Truth(**truth), tracks, seed, rate=500.0, noise=noise, drop_prob=0.01, glitch_prob=0.002,
                           **(starts or {}))
    for drop in drops:
        drop["y"] = drop["y"] + table
    path = write_csv(tmp_path / f"drops_{seed}.csv", drops) or tmp_path / f"drops_{seed}.csv"
    cfg = parse_config(declared)
    trackset = load_tracks(path, sides=4, circumradius=RADIUS)
    report = diagnose(trackset, cfg, seed=split_seed, null_simulations=100, bootstrap=400, **options)
    report.pop("_fits")
    assert_named_effects_are_away_from_null(report, cfg)
    return report


def assert_named_effects_are_away_from_null(report, cfg):
    """Every run: an effect the report names has a final 95 % interval that excludes its null
    (one component for a vector effect), and one removed from the named model is not named;
    each fold's steps still kept a significant gain in that fold's final model; the contract of
    issue 30 holds."""
    for name in report["effects_added"]:
        own = [p.name for p in registry.effect(name).params]
        assert not own or any(null_excluded(n, report["params"][n]["ci95"], cfg) for n in own), (name, report["params"])
    assert not {r["effect"] for r in report["effects_removed"] if r["fold"] is None} & set(report["effects_added"])
    for step in report["chain"]:  # and each step still named keeps a significant gain in the final model
        assert step["removed"] or step["final_z"] > step["threshold_z"], step
    assert_contract(report)


def assert_contract(report):
    """verdict_spread, cause and consistency of each named effect, proposals (issue 30, item 6)."""
    spread = report["verdict_spread"]
    assert spread["verdicts"][0] == report["verdict"] and len(spread["verdicts"]) == 4
    assert set(spread["verdicts"]) <= {"explained", "improved", "unexplained"}
    assert set(report["effects"]) == set(report["effects_added"])
    for name, entry in report["effects"].items():
        assert entry["cause"] in ("cause", "stand_in")
        assert {"test", "passed", "comparisons", "signature", "failed"} <= set(entry["consistency"])
        assert entry["consistency"]["passed"] == (entry["cause"] == "cause")
    if any(e["cause"] == "stand_in" for e in report["effects"].values()):
        assert report["verdict"] != "explained"
    for p in report["proposals"]:
        assert {"target", "terms", "ci95", "heldout_gain"} <= set(p) and set(p["terms"]) == set(p["ci95"])
    if report["after"]["median_multiple_of_floor"] <= 1.5:
        assert report["proposals"] == []
    worst = report["worst_tracks"]
    assert len(worst["before"]) == len(worst["after"]) == min(5, report["data"]["usable_tracks"])
    assert worst["before"][0]["before"] == max(w["before"] for w in worst["before"])


def causes(report):
    return {name: entry["cause"] for name, entry in report["effects"].items()}


# The truth must lie within the reported 95 % interval widened WIDEN times about the estimate.
# Calibrated, not chosen to pass: the loop's intervals cover about 90 % (friction 43/48,
# scripts/coverage_measured.py; the track bootstrap is about 1.3 times too narrow: docs/dev/
# measured_intervals.md), and this file checks some 25 intervals, so the plain 95 % interval
# would fail a run by chance about two times in three. 1.3 x 3.09 / 1.96 = 2.05, used as 2.0: a 0.2 % miss
# per check at the measured width, 5 % for the file. Caught: time_scale 9.0516 [9.0193,
# 9.0680] for 9.0699 and air_drag 0.8154 [0.8001, 0.8365] for 0.8 (two effects at once),
# the same to 1e-10 at fac92d9 and d3de25b; the intervals' coverage itself is measured by
# scripts/coverage_measured.py, not here.
WIDEN = 2.0


def within(value, interval, truth):
    low, high = interval
    return value - WIDEN * (value - low) <= truth <= value + WIDEN * (high - value)


def covers(report, name, value):
    entry = report["params"][name]
    return within(entry["value"], entry["ci95"], value)


def test_nothing_to_find_adds_nothing(tmp_path):
    report = run_loop(tmp_path, TRUTH)
    assert report["effects_added"] == []
    assert report["verdict"] == "explained"
    # reference values: within 2 % (the intervals' coverage is measured by scripts/coverage_measured.py)
    assert report["params"]["beta_normal"]["value"] == pytest.approx(0.4, rel=0.02)
    assert report["params"]["friction"]["value"] == pytest.approx(0.3, rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("split_seed", [1, 2, 3])
def test_nothing_to_find_on_other_splits(tmp_path, split_seed):
    report = run_loop(tmp_path, TRUTH, split_seed=split_seed)
    assert report["effects_added"] == []
    assert report["verdict"] == "explained"


LIBRARY_CASES = {
    # effect: (extra truth, declared config, parameter -> true value)
    "corner_impulse": ({"friction": math.inf}, DECLARED_PAPER, {}),
    "air_drag": ({"air_drag": 0.8}, DECLARED_RIGID, {"air_drag": 0.8}),
    "com_offset": ({"com_offset": (0.004, -0.002)}, DECLARED_RIGID, {"com_dx": 0.004, "com_dy": -0.002}),
    "speed_restitution": ({"speed_restitution": 0.6}, DECLARED_RIGID, {"speed_restitution": 0.6}),
    "gravity": ({"g": 9.3}, DECLARED_RIGID, {"g": 9.3}),
    "angle_offset": ({"angle_offset": 0.05}, DECLARED_RIGID, {"angle_offset": 0.05}),
    "time_scale": ({"time_scale": 1.04}, DECLARED_RIGID, {"time_scale": 1.04}),
    "length_scale": ({"length_scale": 0.96}, DECLARED_RIGID, {"length_scale": 0.96}),
    "table_offset": ({"table_offset": 0.002}, DECLARED_RIGID, {"table_offset": 0.002}),
    # new contact physics (the friction rules with a friction of 0.2, so that the cone binds often);
    "inertia": ({"inertia": 0.85}, DECLARED_RIGID, {"inertia": 0.85}),
    "rounded_corners": ({"corner_radius": 0.004}, DECLARED_RIGID, {"corner_radius": 0.004}),
    "sliding_friction": ({"friction_rule": "sliding", "friction": 0.2}, DECLARED_RIGID, {"friction": 0.2, "beta_normal": 0.4}),
    "exact_coulomb": ({"friction_rule": "exact", "friction": 0.2}, DECLARED_RIGID, {"friction": 0.2, "beta_normal": 0.4}),
}
NEW_EFFECTS = ("inertia", "rounded_corners", "sliding_friction", "exact_coulomb")


def _apparent_g(report):
    """g / time_scale^2 with its interval: what the motion fixes when either is fitted."""
    params = report["params"]
    if "g" in params:
        return params["g"]["value"], params["g"]["ci95"]
    scale = params["time_scale"]
    return 9.81 / scale["value"] ** 2, sorted(9.81 / s**2 for s in scale["ci95"])


def _check_library_case(tmp_path, effect):
    extra, declared, true_values = LIBRARY_CASES[effect]
    truth = dict(TRUTH, **extra)
    report = run_loop(tmp_path, truth, declared)
    # on the confirmation tracks, which took no part in choosing, the model with the effect
    # predicts better than the declared one (the verdict alone says only that something was
    # added: "explained" or "improved" follow from any effect added)
    assert report["after"]["median_error"] < report["baseline"]["median_error"], (report["baseline"], report["after"])
    if effect in ("gravity", "time_scale"):
        # a clock off by s is g / s^2 to every motion of this model: either name is right, the
        # loop names them once (it does not fit the second after the first), and the apparent
        # g must be the truth's
        assert report["effects_added"][:1] in (["gravity"], ["time_scale"]), report["rounds"]
        added = report["effects_added"][0]
        other = "time_scale" if added == "gravity" else "gravity"
        assert other not in report["effects_added"] and report["equivalent_effects"] == {added: [other]}
        value, (low, high) = _apparent_g(report)
        true_g = truth.get("g", 9.81) / truth.get("time_scale", 1.0) ** 2
        assert within(value, (low, high), true_g), (value, low, high, true_g)
        return report
    assert report["effects_added"][:1] == [effect], report["rounds"]
    for name, value in true_values.items():
        entry = report["params"][name]
        if not covers(report, name, value) and entry["one_track_decides"]:
            # the report says the interval is not to be trusted: one track (a prediction near a
            # discontinuity) carries most of the information; com_dx on this set: 99 % of it,
            # 0.00396 [0.00342, 0.00396] for 0.004
            pytest.xfail(f"{name}: one track carries {entry['top_track_share']:.0%} of its information; the report flags it")
        assert covers(report, name, value), (name, entry)
    return report


def test_a_flight_effect_is_named_and_measured(tmp_path):
    report = _check_library_case(tmp_path, "air_drag")
    assert report["verdict"] == "explained"
    assert report["after"]["test_error"] < report["baseline"]["test_error"]
    # the same drag on the two halves of the tracks and on first and later flights (seed 1:
    # 0.797 and 0.804, z = -1.2; 0.799 and 0.801, z = -0.3), and the deceleration was in the
    # declared model's residual: a cause
    assert causes(report) == {"air_drag": "cause"}, report["effects"]
    assert set(report["verdict_spread"]["verdicts"]) == {"explained"}


# rounded_corners once missed the plain 95 % interval: corner_radius 0.0039874 [0.0039736,
# 0.0039956] for 0.004 on split 0 (split 1: 0.0039994 [0.0039913, 0.0040076]); WIDEN (above)
# is the calibrated check.
@pytest.mark.slow
@pytest.mark.parametrize("effect", [e for e in LIBRARY_CASES if e != "air_drag"])
def test_every_library_effect_alone(tmp_path, effect):
    _check_library_case(tmp_path, effect)


@pytest.mark.slow
# "sliding" was an xfail: com_dy -0.0020715 [-0.0021055, -0.0020471] for -0.002 once; it passed
# on 2026-11-27 with the plain interval and on 2026-11-28 with WIDEN's, so the mark is gone.
@pytest.mark.parametrize("rule", ["sliding", "exact"])
def test_a_loaded_die_is_measured_under_a_friction_rule_the_config_lacks(tmp_path, rule):
    """The drops slide by another friction rule than the declared ("aimed") one, with a friction
    of 0.2 so that the cone binds often, and the die is loaded: the loop must still name
    com_offset with the truth inside its intervals (it may name the friction rule too; nothing
    else)."""
    truth = dict(TRUTH, friction_rule=rule, friction=0.2, com_offset=(0.004, -0.002))
    report = run_loop(tmp_path, truth, DECLARED_RIGID)
    assert "com_offset" in report["effects_added"], report["rounds"]
    assert set(report["effects_added"]) <= {"com_offset", "sliding_friction", "exact_coulomb"}, report["effects_added"]
    for name, value in (("com_dx", 0.004), ("com_dy", -0.002)):
        entry = report["params"][name]
        if not covers(report, name, value) and entry["one_track_decides"]:
            pytest.xfail(f"{name}: one track carries {entry['top_track_share']:.0%} of its information; the report flags it")
        assert covers(report, name, value), (name, entry)


@pytest.mark.slow
@pytest.mark.parametrize("effect", NEW_EFFECTS)
def test_a_second_draw_of_the_same_physics_names_the_same_effects(tmp_path, effect):
    extra, declared, _ = LIBRARY_CASES[effect]
    truth = dict(TRUTH, **extra)
    first = run_loop(tmp_path, truth, declared, seed=1)
    second = run_loop(tmp_path, truth, declared, seed=2)
    assert set(first["effects_added"]) == set(second["effects_added"]), (first["rounds"], second["rounds"])


@pytest.mark.slow
def test_two_effects_at_once(tmp_path):
    truth = dict(TRUTH, air_drag=0.8, com_offset=(0.004, 0.0))
    report = run_loop(tmp_path, truth)
    assert sorted(report["effects_added"]) == ["air_drag", "com_offset"]
    assert report["verdict"] == "explained"
    assert covers(report, "air_drag", 0.8), report["params"]["air_drag"]
    assert covers(report, "com_dx", 0.004), report["params"]["com_dx"]


# The flat_landing effect (contact time T) needs landings near flat: a landing tilted by theta
# has its second corner d = S sin(theta) / v after the first (S = 6 cm, v about 2.4 m/s:
# d = 0.025 s per rad), and shares the impact only when d < T. With the usual starts (phi
# uniform, spin up to 8 rad/s) 12 of 577 impacts come within T = 8e-4 s (seed 1). So the drops start
# within 0.03 rad of a flat side (phi = pi/4 for the square) with spin within +-0.3 rad/s (at
# most 0.02 rad more over the 0.05 s fall), and T = 8e-4 s, near the upper bound 1e-3 s where
# the effect is largest, but inside it so that an interval can cover the truth from both sides.
# On this set (seed 1) 79 of 90 first landings share the impact, at shares from 0.17 to 0.92
# (10th to 90th percentile); 82 of 493 impacts in all (the later ones are tilted by the spin the
# blended first landing leaves).
FLAT_LANDING_TRUTH = dict(TRUTH, contact_time=8e-4)
FLAT_LANDING_STARTS = {"phi": (math.pi / 4 - 0.03, math.pi / 4 + 0.03), "spin": (-0.3, 0.3)}


@pytest.mark.slow
def test_flat_landing_contact_time_is_found(tmp_path):
    """Caught: the candidate ended at the bound 1e-3 s and angle_offset was named instead; its
    flights refreshed from their guesses at the fitted values (diagnose.fit_candidate) it is
    found."""
    report = run_loop(tmp_path, FLAT_LANDING_TRUTH, starts=FLAT_LANDING_STARTS)
    print("flat_landing:", report["effects_added"], report["verdict"], report["params"]["contact_time"])
    assert report["effects_added"][:1] == ["flat_landing"], report["rounds"]
    assert report["verdict"] in ("explained", "improved")
    assert covers(report, "contact_time", 8e-4), report["params"]["contact_time"]


FLAT_LANDING_DECLARED = DECLARED_RIGID.replace("beta_normal = 0.3", "beta_normal = 0.4").replace("friction = 0.5", "friction = 0.3") + (
    "[effects]\ncontact_time = 8e-4\n")


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason=(
    "open defect (docs/dev/measured_intervals.md, 2026-11-28): fold 1 names angle_offset 0.0125 [0.0090, 0.0222] rad "
    "(z 4.51) as a cause because flat_landing, the true effect, has the higher z (4.60) but an interval that holds its "
    "null, so the next candidate is taken; the same at fac92d9"))
def test_an_effect_back_near_its_null_is_not_named(tmp_path):
    # flat landings with a contact time of 5e-4 s: on the 70 % selection tracks of the loop
    # before cross-fitting, angle_offset was added in round 1 at 0.013 rad (z = 3.59; the
    # flat_landing candidate ended at 1.3e-4 s with an interval that holds 0), and the later
    # rounds' refits brought it to 0.0036 [0.0015, 0.0056] rad: clear of 0, but its gain in the
    # final model z = 0.95 against the 2.49 it passed; the final checks took it out. On each
    # cross-fitting half a fold may add it and take it out again, or not add it at all: either
    # way it is not named, and the drops are not explained.
    report = run_loop(tmp_path, dict(TRUTH, contact_time=5e-4), starts=FLAT_LANDING_STARTS)
    assert "angle_offset" not in report["effects_added"] and "angle_offset" not in report["params"]
    for step in report["chain"]:
        if "angle_offset" in step["effects"]:
            assert step["removed"] == ["angle_offset"]
    assert report["verdict"] != "explained"


def test_an_effect_is_away_from_its_null_by_its_intervals():
    cfg = parse_config(DECLARED_RIGID)
    params = {"com_dx": {"ci95": [0.001, 0.002]}, "com_dy": {"ci95": [-0.001, 0.001]}, "angle_offset": {"ci95": [-0.0006, 0.0053]},
              "air_drag": {"ci95": [math.nan, math.nan]}}
    assert effect_away_from_null("com_offset", params, cfg)  # one component is enough
    assert not effect_away_from_null("angle_offset", params, cfg)
    assert not effect_away_from_null("air_drag", params, cfg)  # no interval excludes nothing
    assert effect_away_from_null("corner_impulse", params, cfg)  # a switch, no parameter
    params["com_dx"]["ci95"] = [-0.001, 0.002]
    assert not effect_away_from_null("com_offset", params, cfg)


@pytest.mark.slow
def test_flat_landing_truth_declared_is_explained(tmp_path):
    # the same drops with the truth declared: the loop's fit of the kernel reproduces the
    # generator's flat landings (the xfail above is the loop's search, not the physics)
    report = run_loop(tmp_path, FLAT_LANDING_TRUTH, FLAT_LANDING_DECLARED, starts=FLAT_LANDING_STARTS)
    assert report["effects_added"] == []
    assert report["verdict"] == "explained"
    assert covers(report, "contact_time", 8e-4), report["params"]["contact_time"]
    assert report["params"]["contact_time"]["value"] == pytest.approx(8e-4, rel=0.02)


# magnus 0.1: at 0.05 the fitted model's median track error on this set is 1.48 x the noise
# floor, within the 1.5 x of `explained` (a force too weak to see at this noise). Both run in
# `make test-measured` only: spin damping took 93 s of the default suite, then at 9 min 17 s of
# its 10 minutes. The default suite keeps physics outside the library in
# tests/measured/test_propose.py (spin drag, a tilted table, restitution by corner: the
# declared model fitted, then the formula for what it leaves).
@pytest.mark.slow
@pytest.mark.parametrize("outside", [{"spin_damping": 3.0}, {"magnus": 0.1}])
def test_physics_outside_the_library_is_unexplained(tmp_path, outside):
    report = run_loop(tmp_path, dict(TRUTH, **outside))
    assert set(causes(report).values()) <= {"stand_in"}, report["effects"]  # nothing named a cause
    assert report["verdict"] == "unexplained"
    assert report["signatures_remaining"]
    assert report["proposals"]  # a formula for what is left


# Issue 30: two draws of one physics get one verdict (before cross-fitting, two draws of 36
# drops with inertia 0.8 of eq. 25's got `explained` at 1.56 times the floor and `unexplained`
# at 6.2 times, each from its 11 confirmation tracks). Inertia is in the library now: seeds 1
# and 2 name it a cause (0.8006 and 0.8011 on the two halves of seed 1, z = -0.7), median
# 0.99 and 1.05 times the floor. A compliant contact of 0.5 ms is not: seed 1 names
# table_offset, seed 2 table_offset and g, each a stand-in (first against later flights:
# table_offset -1.29 against -0.20 mm, z = -8.8; z = -6.7 and -5.0 on seed 2), so no cause:
# `unexplained` both times, with a formula proposed for what is left.
SAME_PHYSICS = {"inertia": ({"inertia": 0.8}, "explained"), "compliant": ({"compliant_time": 5e-4}, "unexplained")}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(SAME_PHYSICS))
def test_the_same_physics_drawn_twice_gets_the_same_verdict(tmp_path, case):
    physics, verdict = SAME_PHYSICS[case]
    reports = [run_loop(tmp_path, dict(TRUTH, **physics), seed=seed) for seed in (1, 2)]
    assert [r["verdict"] for r in reports] == [verdict, verdict], [
        (r["verdict"], causes(r), r["after"]["median_multiple_of_floor"]) for r in reports]
    for report in reports:
        if case == "inertia":
            assert causes(report) == {"inertia": "cause"}, report["effects"]
        else:
            assert set(causes(report).values()) <= {"stand_in"}, report["effects"]
            assert report["proposals"]


@pytest.mark.slow
def test_drag_standing_in_for_a_tilted_table_is_called_a_stand_in(tmp_path):
    """A table tilted by 3 degrees (outside the library): both folds add air_drag, whose value
    agrees on every split (the flights moving towards +x put it at its bound 0 with a wide
    interval), but the named model leaves flight.x_acc ~ 1 at g sin 3 deg: a stand-in, and the
    verdict names no cause (scripts/cause_calibration.py, seeds 1 and 2)."""
    report = run_loop(tmp_path, dict(TRUTH, table_tilt=math.radians(3.0)))
    assert set(causes(report).values()) <= {"stand_in"}, report["effects"]
    assert report["verdict"] == "unexplained"
    constant = {p["target"]: p for p in report["proposals"]}["flight.x_acc"]
    low, high = constant["ci95"]["1"]
    assert low <= 9.81 * math.sin(math.radians(3.0)) * 1.02 and high >= 9.81 * math.sin(math.radians(3.0)) * 0.98, constant


@pytest.fixture(scope="module")
def four_times_the_noise(tmp_path_factory):
    return run_loop(tmp_path_factory.mktemp("noise4"), dict(TRUTH, air_drag=0.8), noise=(8e-4, 16e-3))


@pytest.mark.slow
def test_four_times_the_noise(four_times_the_noise):
    report = four_times_the_noise
    usable = report["data"]["usable_tracks"]
    assert usable >= 0.9 * TRACKS
    assert report["effects_added"][:1] == ["air_drag"]
    assert report["params"]["air_drag"]["value"] == pytest.approx(0.8, rel=0.05)


@pytest.mark.slow
# at 4x the noise this set once gave drag 0.774 [0.730, 0.799] and friction 0.295: a local optimum,
# left since contact candidates start their flights from fresh states (diagnose.fit_candidate) and
# so find the current model's better optimum; now 0.800 [0.785, 0.816] and 0.2996 [0.2978, 0.3010]
def test_four_times_the_noise_interval_covers_the_drag(four_times_the_noise):
    assert covers(four_times_the_noise, "air_drag", 0.8), four_times_the_noise["params"]["air_drag"]
    assert covers(four_times_the_noise, "friction", 0.3), four_times_the_noise["params"]["friction"]


def test_the_declared_model_starts_from_measured_values(tmp_path):
    """Hexagon drops at 1000 Hz (truth beta_normal 0.4, friction 0.3): from the config's 0.3 and
    0.5 the fit stopped near its start (beta_normal 0.301, scripts/coverage_measured.py --sides
    6, seed 1). The start measured impact by impact (calibrate) is close to the truth, the fit
    from it has the lower cost and is kept, and its intervals cover the truth."""
    from dice_sweep.app.measured import run_fit
    from dice_sweep.measured.diagnose import measured_starts
    from dice_sweep.measured.fit import ModelSpec

    radius = 0.025
    truth = Truth(sides=6, circumradius=radius, **TRUTH)
    path = tmp_path / "hexagon.csv"
    write_csv(path, simulate_drops(truth, 90, 101, rate=1000.0, noise=(1e-4, 3e-3), drop_prob=0.01, glitch_prob=0.002))
    cfg = parse_config(DECLARED_RIGID.replace("sides = 4", "sides = 6").replace(f"circumradius = {RADIUS!r}", f"circumradius = {radius!r}"))
    starts = measured_starts(load_tracks(path, sides=6, circumradius=radius), cfg, ModelSpec.of(cfg))
    assert starts["beta_normal"] == pytest.approx(0.4, abs=0.02)
    assert starts["beta_tangential"] == pytest.approx(0.0, abs=0.03)
    assert starts["friction"] == pytest.approx(0.3, abs=0.05)
    result = run_fit(path, cfg, seed=1)
    by_source = {s["source"]: s for s in result["starts"]}
    assert by_source["config"]["params"]["beta_normal"] < 0.35  # the optimum near the config's start
    assert by_source["calibrate"]["chosen"] and by_source["calibrate"]["cost"] < 0.1 * by_source["config"]["cost"]
    for name, value in TRUTH.items():
        if name in result["params"]:
            low, high = result["params"][name]["ci95"]
            assert low <= value <= high, (name, result["params"][name])


def test_drops_released_near_flat_get_no_measured_start(tmp_path):
    """No first impact lands on one corner, so beta_normal is not measured, and a start with
    friction alone is not offered (it hid the flat landing: test_flat_landing_contact_time_is_found)."""
    from dice_sweep.measured.diagnose import measured_starts
    from dice_sweep.measured.fit import ModelSpec

    path = tmp_path / "flat.csv"
    write_csv(path, simulate_drops(Truth(**FLAT_LANDING_TRUTH), 30, 1, rate=500.0, noise=NOISE, **FLAT_LANDING_STARTS))
    cfg = parse_config(DECLARED_RIGID)
    assert measured_starts(load_tracks(path, sides=4, circumradius=RADIUS), cfg, ModelSpec.of(cfg)) == {}
