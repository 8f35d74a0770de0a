"""Free flights and tracking noise (dice_sweep.measured.flights).

Synthetic drops come from tests/measured/independent.py (no project code; true impact times
known), at 500 Hz with 1x and 4x the tracking noise, dropped frames (rows missing from the file
and NaN rows), and glitches the tracker did not flag. The die at rest comes from the kernel
(tests/measured/drops.py), since the independent tracks end before rest. The shared real data is
used when it is there.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from dice_sweep.measured.flights import MIN_FLIGHT_FRAMES, difference_noise, estimate_noise, find_flights, segment_track
from dice_sweep.measured.impacts import rest_pose, table_level
from dice_sweep.measured.tracks import load_tracks
from tests.measured import drops
from tests.measured.independent import Truth, simulate_drops

REAL_DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"
R = 0.06 / math.sqrt(2)  # m, the square of the shared data
RATE = 500.0  # Hz
NOISE = {1: (2e-4, 4e-3), 4: (8e-4, 16e-3)}  # m, rad: 1x and 4x the tracking noise
DROP_PROB = 0.03  # frames missing from the file (time steps of 2-3 frames)
NAN_PROB = 0.02  # frames kept as NaN rows (not usable)
GLITCH_PROB = 0.01  # frames jumping 5-20 mm and 0.3-1 rad, not flagged
TRACKS = 120
END_FRAMES = 2  # a first flight may end this many frames before the last one before the impact
MIN_RIGHT = 0.9  # share of tracks whose first flight must be right
NOISE_TOLERANCE = 0.04  # relative: 100 tracks of ~150 flight frames give sigma to ~1 %
REST_DURATION = 1.2  # s of kernel drops (250 Hz), most of them at rest well before the end
REST_FRAMES = 40  # frames at rest a track must end with to count as resting
REAL_MIN_SHARE = 0.95  # real tracks that must get a first flight of MIN_FLIGHT_FRAMES or more


def noisy_drops(level, seed, count=TRACKS):
    """Independent drops at ``level`` x noise, with NaN rows added; each dict gets ``usable``."""
    sx, sphi = NOISE[level]
    tracks = simulate_drops(Truth(), count, seed, rate=RATE, noise=(sx, sphi), drop_prob=DROP_PROB, glitch_prob=GLITCH_PROB)
    rng = np.random.default_rng(seed)
    for track in tracks:
        missing = rng.random(track["t"].size) < NAN_PROB
        for key in ("x", "y", "phi"):
            track[key] = np.where(missing, np.nan, track[key])
        track["usable"] = ~missing
    return tracks


def arrays(track):
    return track["t"], track["x"], track["y"], track["phi"], track["usable"]


def impact_inside(track, flight):
    """Whether a true impact falls between the flight's first and last frame."""
    t, impacts = track["t"], track["impacts"]
    return bool(np.any((impacts > t[flight[0]]) & (impacts <= t[flight[1]])))


def first_flight_right(track, flights):
    """The first flight ends 0 to END_FRAMES frames before the last usable frame before the first
    impact, and holds no impact."""
    if not flights:
        return False
    t, usable, impacts = track["t"], track["usable"], track["impacts"]
    first = flights[0]
    if impact_inside(track, first):
        return False
    if impacts.size == 0:
        return True
    last_before = t[usable & (t < impacts[0])][-1]
    frames_early = round((last_before - t[first[1]]) * RATE)
    return 0 <= frames_early <= END_FRAMES


@pytest.fixture(scope="module", params=[1, 4], ids=["1x", "4x"])
def level(request):
    return request.param


@pytest.fixture(scope="module")
def synthetic(level):
    return level, noisy_drops(level, seed=10 + level)


@pytest.mark.parametrize("given", [True, False], ids=["noise-given", "noise-estimated"])
def test_first_flights_are_right_and_no_flight_holds_an_impact(synthetic, given):
    level, tracks = synthetic
    sx, sphi = NOISE[level]
    noise = (sx, sx, sphi) if given else None
    found = [find_flights(*arrays(track), sides=4, circumradius=R, noise=noise) for track in tracks]
    right = np.mean([first_flight_right(track, flights) for track, flights in zip(tracks, found)])
    assert right >= MIN_RIGHT
    holding = [(track["traj"], flight) for track, flights in zip(tracks, found) for flight in flights if impact_inside(track, flight)]
    assert holding == []
    for track, flights in zip(tracks, found):
        assert flights[0][0] <= 3  # the first flight starts at (or next to) the first frame
        ends = np.array(flights).ravel()
        assert np.all(np.diff(ends) > 0)  # in time order, not overlapping
        assert all(track["usable"][first] and track["usable"][last] for first, last in flights)
        assert all(last - first + 1 >= MIN_FLIGHT_FRAMES for first, last in flights)


def test_noise_estimate_covers_the_truth(synthetic):
    level, tracks = synthetic
    sx, sphi = NOISE[level]
    truth = np.array([sx, sx, sphi])
    estimate = estimate_noise([arrays(track) for track in tracks], sides=4, circumradius=R)
    assert np.all(np.abs(estimate.sigma / truth - 1.0) < NOISE_TOLERANCE)
    assert np.all((estimate.interval[:, 0] <= truth) & (truth <= estimate.interval[:, 1]))
    pose = math.sqrt(2.0 * sx**2 + (R * sphi) ** 2)
    assert abs(estimate.pose / pose - 1.0) < NOISE_TOLERANCE
    assert estimate.pose_interval[0] <= pose <= estimate.pose_interval[1]
    assert estimate.tracks == len(tracks)
    assert np.all(estimate.dof < estimate.frames)  # the fitted parameters are taken off


def test_difference_noise_of_a_flight():
    rng = np.random.default_rng(3)
    t = np.arange(400) / RATE
    sx, sphi = NOISE[4]
    x = 0.1 - 0.5 * t + sx * rng.normal(size=t.size)
    y = 2.0 + 1.0 * t - 4.905 * t * t + sx * rng.normal(size=t.size)
    phi = 0.3 + 7.0 * t + sphi * rng.normal(size=t.size)
    sigma = difference_noise(t, x, y, phi, np.ones(t.size, dtype=bool), circumradius=R)
    assert np.allclose(sigma, [sx, sx, sphi], rtol=0.15)


def test_track_without_impact_is_one_flight(level):
    sx, sphi = NOISE[level]
    track = simulate_drops(Truth(), 1, 5, rate=RATE, noise=(sx, sphi))[0]
    keep = track["t"] < track["impacts"][0] - 3.0 / RATE
    t, x, y, phi = (track[key][keep] for key in ("t", "x", "y", "phi"))
    assert find_flights(t, x, y, phi, np.ones(t.size, dtype=bool), sides=4, circumradius=R) == [(0, t.size - 1)]


def test_die_at_rest_has_no_flights_after_landing():
    times, truth = drops.simulate(drops.die_config(), drops.real_like_states(12, seed=4), duration=REST_DURATION)
    rng = np.random.default_rng(4)
    sx, sphi = NOISE[1]
    resting = 0
    for states in truth:
        moving = np.flatnonzero(np.abs(np.diff(states[:, 3:], axis=0)).max(axis=1) > 0.0)
        rest = int(moving[-1]) + 1  # the die does not move from this frame on
        if rest > times.size - REST_FRAMES:
            continue  # still rocking at the end
        resting += 1
        pose = states[:, :3] + rng.normal(size=(times.size, 3)) * [sx, sx, sphi]
        seg = segment_track(times, pose[:, 0], pose[:, 1], pose[:, 2], np.ones(times.size, dtype=bool), sides=4, circumradius=R)
        assert seg.flights and seg.flights[-1][1] < rest
        assert seg.contact is not None and seg.contact <= rest
    assert resting >= 6
    # a die at rest all along has no flight at all
    still = truth[0, -1, :3] + rng.normal(size=(times.size, 3)) * [sx, sx, sphi]
    assert find_flights(times, still[:, 0], still[:, 1], still[:, 2], np.ones(times.size, dtype=bool), sides=4, circumradius=R) == []


@pytest.mark.skipif(not REAL_DATA.exists(), reason="shared real data not present")
def test_real_drops_get_a_first_flight():
    trackset = load_tracks(REAL_DATA, sides=4, circumradius=R, angle="auto")
    rests = [rest_pose(tr.x, tr.y, tr.phi, tr.usable, R) for tr in trackset.tracks]
    table = table_level([p for p in rests if p is not None], sides=4, circumradius=R)
    # (its speed is timed by scripts/bench_measured.py, not here: a test asserted < 2 s and
    # failed at 2.7 s on a loaded 2-core machine)
    found = [find_flights(tr.t, tr.x, tr.y, tr.phi, tr.usable, sides=4, circumradius=R, table=table) for tr in trackset.tracks]
    first = np.array([flights[0][1] - flights[0][0] + 1 if flights else 0 for flights in found])
    assert np.mean(first >= MIN_FLIGHT_FRAMES) >= REAL_MIN_SHARE
