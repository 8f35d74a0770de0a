"""Tests of dice_sweep.measured.report: the --effects list, JSON-ready values, the residual curves
and the Markdown report of a diagnose report written by hand."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from dice_sweep import effects as registry
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.report import jsonable, markdown_report, parse_effects, residual_curves


def test_effects_are_read_from_a_comma_list():
    first, second = registry.names()[:2]
    assert parse_effects(f" {first}, {second} ,") == (first, second)
    assert parse_effects("") == parse_effects(None) == ()
    with pytest.raises(DiceSweepError) as error:
        parse_effects(f"{first},magic,other")
    assert str(error.value) == f"--effects: unknown effect 'magic' (allowed: {', '.join(registry.names())})"


def test_jsonable_turns_numpy_values_into_json_and_non_finite_numbers_into_null():
    value = {1: np.float64(0.5), "a": (np.int32(3), np.bool_(True), [np.nan, math.inf, 2.0]), "s": "text", "n": None}
    out = jsonable(value)
    assert out == {"1": 0.5, "a": [3, True, [None, None, 2.0]], "s": "text", "n": None}
    assert type(out["a"][0]) is int and type(out["a"][1]) is bool and type(out["1"]) is float
    assert json.loads(json.dumps(out, allow_nan=False)) == out


def test_residual_curves_are_the_pose_errors_against_time_from_the_first_impact():
    # two tracks, their first impacts at 0.10 s and 0.25 s; one flight segment each, starting
    # at frame 2 of its track, with frames 0.01 s and 0.02 s into the segment
    prepared = [SimpleNamespace(t_impact=0.10, t=np.array([0.0, 0.05, 0.12]), flights=[(2, 3)]),
                SimpleNamespace(t_impact=0.25, t=np.array([0.0, 0.1, 0.2]), flights=[(2, 3)])]
    segments = SimpleNamespace(count=2, tracks=2, track=np.array([0, 1]), times=np.array([0.01, 0.02, 0.01, 0.02]),
                               segment_rows=np.array([0, 0, 1, 1]), track_rows=np.array([0, 0, 1, 1]))
    residual = np.array([[3e-3, 4e-3, 0.0], [0.0, 0.0, 1e-3], [1e-3, 0.0, 0.0], [0.0, 2e-3, 0.0]])
    (label, since, error), = residual_curves({"after": residual}, prepared, segments)
    assert label == "after"
    np.testing.assert_allclose(since, [0.03, 0.04, -0.04, -0.03], rtol=0, atol=1e-15)
    np.testing.assert_allclose(error, [5e-3, 1e-3, 1e-3, 2e-3], rtol=1e-15)


def report(verdict="explained", remaining=()):
    entry = {"effects": [], "test_error": 0.002, "ci95": [0.0015, 0.0025], "multiple_of_floor": 2.0, "median_error": 0.0018,
             "median_ci95": [None, None], "median_multiple_of_floor": 1.8,
             "params": {"beta_normal": {"value": 0.41, "ci95": [0.39, 0.43], "unit": "", "at_bound": False, "top_track_share": 0.2},
                        "friction": {"value": 0.5, "ci95": [None, None], "unit": "", "at_bound": True}}}
    return {
        "noise_floor": 0.001, "verdict": verdict, "effects_added": ["air_drag"], "metric": "m", "selection": "s",
        "data": {"path": "d.csv", "tracks": 20, "rate_hz": 500.0, "selection_tracks": 10, "selection_flights": 40,
                 "confirmation_tracks": 10, "confirmation_flights": 38, "glitch_frames": 1, "gap_frames": 2},
        "noise": {"sigma_x": 1e-4, "sigma_y": 2e-4, "sigma_phi": 3e-3, "pose_ci95": [0.0009, 0.0011]},
        "angle_reading": "--angle as-is", "baseline": entry, "after": {**entry, "effects": ["air_drag"], "test_error": None},
        "verdict_rule": "r", "rounds": [{"threshold_z": 2.5, "sidak_z": 2.4, "null_simulations": 200, "candidates": [
            {"effect": "air_drag", "test_error": 0.0015, "median_error": 0.0014, "z": 3.14159, "excess_share": 0.25,
             "null_excluded": True, "at_bound": [], "accepted": True}]}],
        "signatures": [{"signature": "drag", "value": None, "ci95": [None, None], "unit": "1/m", "points_to": ["air_drag"], "note": "n"}],
        "signatures_remaining": list(remaining),
    }


def test_the_markdown_report_has_the_verdict_the_tables_and_n_a_for_missing_numbers():
    text = markdown_report(report())
    lines = text.splitlines()
    assert lines[0] == "# Diagnosis of tracked drops" and text.endswith("\n")
    assert "**Verdict: explained.** Effects added: air_drag." in lines
    assert "| baseline | none | 2.000 mm | [1.500, 2.500] mm | 2.0 | 1.800 mm | n/a | 1.8 |" in lines
    assert "| after | air_drag | n/a | [1.500, 2.500] mm | 2.0 | 1.800 mm | n/a | 1.8 |" in lines  # test_error None
    assert "| beta_normal | 0.41 | [0.39, 0.43] |  | no | 20% |" in lines
    assert "| friction | 0.5 | n/a |  | yes | - |" in lines
    assert "| air_drag | 1.500 mm | 1.400 mm | 3.14 | 25% | yes | - | yes |" in lines
    assert "| drag | n/a | n/a | 1/m | air_drag | n |" in lines
    assert "Not explained" not in text


def test_a_report_not_explained_says_what_is_left():
    text = markdown_report(report("unexplained", remaining=["drag"]))
    assert "**Not explained:** the median track error after is 1.8 times the noise floor. Signatures left (interval excludes 0): drag." in text
    assert "the misfit is at the impacts" in markdown_report(report("improved"))
