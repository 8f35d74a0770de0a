"""Cause or stand-in (dice_sweep.measured.consistency): two parts' values compared by their
intervals, a signature present before, and nothing left where an effect acts. The whole test
on independent drops runs in tests/measured/test_diagnose.py (slow)."""

import math

import numpy as np
import pytest

from dice_sweep.measured import consistency


def test_two_parts_agree_within_their_intervals():
    def part(value, low, high):
        return {"params": {"g": {"value": value, "ci95": [low, high], "identified": True}}}

    same = consistency.compare("g", part(9.30, 9.28, 9.32), part(9.31, 9.29, 9.33))
    assert same["agree"] and abs(same["z"]) < 1
    apart = consistency.compare("g", part(9.30, 9.28, 9.32), part(9.40, 9.38, 9.42))
    # sd = 0.02 / 1.96 on each side: z = -0.1 / (sqrt(2) * 0.0102) = -6.9
    assert not apart["agree"] and apart["z"] == pytest.approx(-0.1 / (math.sqrt(2) * 0.02 / 1.959963984540054))
    blind = consistency.compare("g", part(9.30, 9.28, 9.32), {"params": {"g": {"value": 9.5, "ci95": [math.nan, math.nan],
                                                                                 "identified": False}}})
    assert blind["agree"] and not blind["testable"]


def test_a_signature_is_present_when_its_interval_says_so():
    floor = 3e-4

    def entry(name, low, high):
        return {"signature": name, "value": (low + high) / 2, "ci95": [low, high]}

    assert consistency.signature_present(entry("flight_deceleration", 0.2, 0.5), floor)
    assert not consistency.signature_present(entry("flight_deceleration", -0.05, 0.003), floor)
    assert consistency.signature_present(entry("impact_prediction", 9e-6, 5e-5), floor)  # inertia 0.8 of eq. 25's
    assert not consistency.signature_present(entry("impact_prediction", -5e-5, 1e-4), floor)
    # the wobble is an amplitude: the noise keeps it above 0, so it counts above half the floor
    assert not consistency.signature_present(entry("flight_wobble_at_spin", 9e-5, 2e-4), floor)
    assert consistency.signature_present(entry("flight_wobble_at_spin", 1.4e-3, 1.7e-3), floor)
    assert consistency.signature_present({"signature": "flight_deceleration", "value": None, "ci95": [None, None]}, floor) is None


def test_an_effect_that_leaves_a_formula_where_it_acts_is_a_stand_in():
    def judged(*names):
        return {name: {"cause": "cause", "consistency": {"passed": True, "failed": []}} for name in names}

    # drag named for a table tilted by 3 degrees (seed 1): flight.x_acc ~ 1 (0.50 m/s^2) left
    tilt = [{"target": "flight.x_acc", "terms": {"1": 0.5013, "vx": 0.1174}, "heldout_gain": 0.989},
            {"target": "impact.dvy", "terms": {"u_n": 0.0127}, "heldout_gain": 0.145}]
    out = consistency.left_where_it_acts(judged("air_drag", "inertia", "table_offset"), tilt)
    assert out["air_drag"]["cause"] == "stand_in" and [p["target"] for p in out["air_drag"]["consistency"]["left"]] == ["flight.x_acc"]
    # contact effects (impact misfits are a catch-all) and measurement effects (they act
    # everywhere) are not tested so
    assert out["inertia"]["cause"] == "cause" and out["table_offset"]["cause"] == "cause"
    assert consistency.left_where_it_acts(judged("air_drag"), [])["air_drag"]["cause"] == "cause"


def test_flight_index_counts_flights_within_each_track():
    from types import SimpleNamespace

    # three tracks with 2, 1 and 3 flights
    segments = SimpleNamespace(count=6, track=np.array([0, 0, 1, 2, 2, 2]), track_segment_starts=np.array([0, 2, 3]))
    assert consistency.flight_index(segments).tolist() == [0, 1, 0, 0, 1, 2]


def test_parts_that_stayed_at_their_start_cannot_agree():
    def part(value, low, high):
        return {"params": {"friction": {"value": value, "ci95": [low, high], "identified": True}}}

    # the real drops' friction on two halves: both part fits stayed within 3e-5 of the value on
    # all tracks that they started from, where two halves that refit differ by about 3e-3
    stuck = consistency.compare("friction", part(0.07955, 0.0731, 0.0857), part(0.07957, 0.0735, 0.0853), start=0.07957)
    assert not stuck["moved"] and not stuck["testable"] and stuck["agree"]
    refit = consistency.compare("friction", part(0.0781, 0.0731, 0.0857), part(0.0809, 0.0735, 0.0853), start=0.07957)
    assert refit["moved"] and refit["testable"] and refit["agree"]
    # without a start (a comparison of two fits from their own starts) a finite z is testable
    assert consistency.compare("friction", part(0.07955, 0.0731, 0.0857), part(0.07957, 0.0735, 0.0853))["testable"]


def test_an_effect_no_split_could_refit_is_a_stand_in():
    from types import SimpleNamespace

    count = 40
    segments = SimpleNamespace(count=count, track=np.arange(count) // 2, track_segment_starts=np.arange(0, count, 2))
    states = np.zeros((count, 6))
    states[::3, 3] = -0.1  # some flights move towards -x
    fit = SimpleNamespace(spec=SimpleNamespace(effects=("coulomb_friction",)), states=states, params={"friction": 0.08})

    def parts(shift):
        def mapper(function, tasks):
            return [{"segments": 20, "tracks": 10, "params": {"friction": {"value": 0.08 + (shift if k % 2 else -shift),
                                                                           "ci95": [0.074, 0.086], "identified": True}}}
                    for k, _ in enumerate(tasks)]
        return mapper

    halves = np.arange(count) < count // 2
    args = (None, fit, None, segments, halves, [], 1e-4, 0, None, 10)
    stuck = consistency.consistency(*args, mapper=parts(1e-5))["coulomb_friction"]
    assert stuck["cause"] == "stand_in" and any(f.startswith("untested") for f in stuck["consistency"]["failed"])
    refit = consistency.consistency(*args, mapper=parts(1e-3))["coulomb_friction"]
    assert refit["cause"] == "cause", refit["consistency"]["failed"]
    apart = consistency.consistency(*args, mapper=parts(6e-3))["coulomb_friction"]
    assert apart["cause"] == "stand_in" and not any(f.startswith("untested") for f in apart["consistency"]["failed"])
