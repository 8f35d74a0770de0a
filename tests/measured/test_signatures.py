"""dice_sweep.measured.signatures: structure planted in a residual is found and named."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dice_sweep import effects as registry
from dice_sweep.measured.signatures import SIGNATURES, remaining_signatures, residual_signatures

RADIUS = 0.04
TRACKS, FRAMES = 12, 40


def segments(rng):
    """One flight of FRAMES frames per track (no predicted rows): the attributes the signatures read."""
    t = np.tile(np.arange(FRAMES) / 250.0, TRACKS)
    track_rows = np.repeat(np.arange(TRACKS), FRAMES)
    vx = rng.uniform(0.2, 0.5, TRACKS)[track_rows]
    measured = np.column_stack([vx * t, 0.2 - 0.5 * 9.81 * t * t, 3.0 * t])
    return SimpleNamespace(tracks=TRACKS, track=np.arange(TRACKS), starts=np.arange(TRACKS + 1) * FRAMES, times=t, measured=measured,
                           predicted=np.zeros(t.size, bool), track_rows=track_rows)


def by_name(found):
    return {s["signature"]: s for s in found}


def test_a_vertical_curvature_left_in_the_flights_is_found_and_named():
    seg = segments(np.random.default_rng(1))
    rng = np.random.default_rng(2)
    residual = rng.normal(0.0, 1e-5, (seg.times.size, 3))
    residual[:, 1] -= 0.5 * 0.3 * seg.times**2  # the tracks fall 0.3 m/s^2 slower than the model
    found = by_name(residual_signatures(None, seg, residual, RADIUS))
    assert set(found) == set(SIGNATURES)
    curvature = found["flight_vertical_curvature"]
    assert curvature["value"] == pytest.approx(0.3, rel=0.05) and curvature["ci95"][0] > 0.2 and curvature["tracks"] == TRACKS
    assert set(curvature["points_to"]) == {e.name for e in registry.EFFECTS if e.signature == "flight_vertical_curvature"} >= {"gravity"}
    assert abs(found["flight_spin_change"]["value"]) < 0.05  # nothing planted in the angle
    assert math.isnan(found["impact_prediction"]["value"])  # no predicted rows
    left = remaining_signatures(list(found.values()), floor=1e-4)
    assert "flight_vertical_curvature" in left and "flight_spin_change" not in left


def test_remaining_signatures_by_their_intervals():
    found = [{"signature": "flight_deceleration", "value": 0.1, "ci95": [0.05, 0.2]},
             {"signature": "flight_spin_change", "value": 0.1, "ci95": [-0.05, 0.2]},
             {"signature": "impact_prediction", "value": 3e-4, "ci95": [2e-4, 4e-4]},
             {"signature": "flight_wobble_at_spin", "value": 1e-4, "ci95": [0.4e-4, 2e-4]},
             {"signature": "flight_vertical_curvature", "value": math.nan, "ci95": [math.nan, math.nan]}]
    # a signed one whose interval excludes 0; an amplitude whose interval lies above half the floor
    assert remaining_signatures(found, floor=2e-4) == ["flight_deceleration", "impact_prediction"]
    assert remaining_signatures(found, floor=0.6e-4) == ["flight_deceleration", "impact_prediction", "flight_wobble_at_spin"]
