"""Tests of dice_sweep.measured.impacts on tracks written by hand: a square dropped corner first
without spin bounces straight up (restitution e), so where its impacts are, the motion on each
side of them, the touching corner and the tilt are known in closed form; a track ending still
gives its rest pose and the table's level."""

import math

import numpy as np
import pytest

from dice_sweep.measured.impacts import (
    find_impacts,
    fit_impact,
    landing_tilt,
    lowest_height,
    rest_pose,
    table_level,
    touching_corner,
    track_impacts,
)

G, R, RATE, E = 9.81, 0.0134, 500.0, 0.5
DIE = {"sides": 4, "circumradius": R}
DOWN = -math.pi / 2  # a square's corner 0 straight down below the centre


def corner_first_drop(y0=0.1, vx=0.2, bounces=2):
    """Frames (t, x, y, phi) of the drop, and its impact times: between impacts the centre flies
    in closed form; each impact sends it straight up at E times the speed it came in with. The
    track ends in the flight after the last impact, before the next contact."""
    hits, start, height, speed = [], 0.0, y0, 0.0
    for _ in range(bounces):
        hits.append(start + (speed + math.sqrt(speed**2 + 2 * G * (height - R))) / G)
        speed = E * G * (hits[-1] - start) - E * speed
        start, height = hits[-1], R
    t = np.arange(0.0, start + 1.8 * speed / G, 1.0 / RATE) + 0.3 / RATE  # frames off the impact times
    y = np.empty_like(t)
    start, height, speed = 0.0, y0, 0.0
    for hit in [*hits, math.inf]:
        inside = (t >= start) & (t < hit)
        dt = t[inside] - start
        y[inside] = height + speed * dt - 0.5 * G * dt**2
        if hit < math.inf:
            speed = E * G * (hit - start) - E * speed
            start, height = hit, R
    return t, vx * t, y, np.full_like(t, DOWN), hits


def test_heights_tilts_and_touching_corners_by_hand():
    assert lowest_height(4, R, 0.05, DOWN) == pytest.approx(0.05 - R, rel=1e-14)
    assert lowest_height(4, R, 0.05, DOWN + math.pi / 4, table=0.01) == pytest.approx(0.05 - R / math.sqrt(2) - 0.01, rel=1e-14)
    np.testing.assert_allclose(lowest_height(4, R, np.array([0.02, 0.03]), np.array([DOWN, DOWN])), [0.02 - R, 0.03 - R])
    assert landing_tilt(4, DOWN) == pytest.approx(math.pi / 4)  # corner down
    assert landing_tilt(4, DOWN + math.pi / 4) == pytest.approx(0.0, abs=1e-15)  # flat
    assert landing_tilt(6, DOWN + 0.1) == pytest.approx(math.pi / 6 - 0.1)
    np.testing.assert_allclose(touching_corner(4, R, DOWN), [0.0, -R], atol=1e-17)
    np.testing.assert_allclose(touching_corner(4, R, DOWN + 0.2), [R * math.cos(DOWN + 0.2), R * math.sin(DOWN + 0.2)])


def test_impacts_are_found_at_the_frames_nearest_the_contacts():
    t, x, y, phi, hits = corner_first_drop()
    usable = np.ones(t.size, bool)
    found = find_impacts(t, y, phi, usable, **DIE)
    assert len(found) == 2
    for frame, hit in zip(found, hits):
        assert abs(t[frame] - hit) <= 1.0 / RATE  # the frame at the lowest height, beside the contact
    assert find_impacts(t, y, phi, np.zeros(t.size, bool), **DIE) == []  # nothing usable, nothing found


def test_each_side_of_an_impact_is_followed_to_the_contact():
    t, x, y, phi, hits = corner_first_drop()
    usable = np.ones(t.size, bool)
    frames = find_impacts(t, y, phi, usable, **DIE)
    impact = fit_impact(t, x, y, phi, usable, frames[0], following=frames[1], **DIE)
    fall = hits[0]
    for side in (impact.before, impact.after):
        assert side.touched and side.frames == 5 and side.rms < 1e-12
        assert side.t_contact == pytest.approx(hits[0], abs=2e-4)  # found on a grid of a few samples a frame
        assert -2e-5 < side.state[1] - R <= 0.0  # the corner at the table, to the sampling of the search
        assert side.state[0] == pytest.approx(0.2 * side.t_contact, rel=1e-9)  # x: the same flight
        assert (side.state[2], side.state[3], side.state[5]) == pytest.approx((DOWN, 0.2, 0.0), abs=1e-9)
    assert impact.before.state[4] == pytest.approx(-G * fall, rel=1e-3)
    assert impact.after.state[4] == pytest.approx(E * G * fall, rel=1e-3)
    np.testing.assert_allclose(impact.corner, [0.0, -R], atol=1e-9)
    assert abs(impact.gap_frames) < 0.1 and impact.mismatch < 1e-5


def test_dropped_frames_during_an_impact_show_as_gap_frames():
    t, x, y, phi, _ = corner_first_drop()
    frames = find_impacts(t, y, phi, np.ones(t.size, bool), **DIE)
    hit = frames[0]
    keep = np.ones(t.size, bool)
    keep[hit - 1 : hit + 3] = False  # four frames around the impact lost ...
    keep[hit] = True  # ... but the lowest one
    t_late = t.copy()
    t_late[hit + 3 :] -= 2.0 / RATE  # and the file's times after them two frames early
    impact = fit_impact(t_late, x, y, phi, keep, hit, following=frames[1], **DIE)
    assert impact.gap_frames == pytest.approx(2.0, abs=0.15)
    assert impact.after.state[4] == pytest.approx(E * G * (impact.before.state[4] / -G), rel=1e-3)  # velocities unchanged


def test_too_few_frames_on_a_side_give_no_fit_and_impacts_come_in_order():
    t, x, y, phi, _ = corner_first_drop()
    usable = np.ones(t.size, bool)
    frames = find_impacts(t, y, phi, usable, **DIE)
    sparse = usable.copy()
    sparse[frames[0] + 3 : frames[1]] = False  # 2 frames after the first impact
    assert fit_impact(t, x, y, phi, sparse, frames[0], following=frames[1], **DIE) is None
    fitted = track_impacts(t, x, y, phi, usable, **DIE)
    assert [k for k, _ in fitted] == [0, 1] and all(impact is not None for _, impact in fitted)
    assert [impact.frame for _, impact in fitted] == frames
    assert [k for k, _ in track_impacts(t, x, y, phi, usable, first_only=True, **DIE)] == [0]


def test_a_track_ending_still_has_a_rest_pose_and_gives_the_table_level():
    n = 60
    t = np.arange(n) / RATE
    x, phi = np.full(n, 0.03), np.full(n, DOWN + math.pi / 4)  # lying flat on a side
    y = np.full(n, R / math.sqrt(2) + 0.01)  # on a table 1 cm up
    usable = np.ones(n, bool)
    pose = rest_pose(x, y, phi, usable, R, t)
    assert pose == pytest.approx((0.03, R / math.sqrt(2) + 0.01, DOWN + math.pi / 4))
    assert table_level([pose, pose], **DIE) == pytest.approx(0.01, rel=1e-12)
    assert table_level([], **DIE) == 0.0
    moving = y + 0.5 * R * t  # rising by 0.5 R/s: 0.1 R over the 0.1 s
    assert rest_pose(x, moving, phi, usable, R, t) is None
    turning = phi + np.radians(2.0) * np.arange(n) / n  # 2 degrees over the track
    assert rest_pose(x, y, turning, usable, R, t) is None
    ends_early = usable.copy()
    ends_early[-5:] = False  # the last usable frame 5 before the end: not at rest at the end
    assert rest_pose(x, y, phi, ends_early, R, t) is None
