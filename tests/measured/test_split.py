"""dice_sweep.measured.split: the tracks made ready for a fit, the same for fit and diagnose."""

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured import split as splitting
from dice_sweep.measured.noise import tracking_noise
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_RIGID, RADIUS, TRUTH
from tests.measured.independent import Truth, simulate_drops, write_csv

CFG = parse_config(DECLARED_RIGID)


def trackset(folder, count):
    path = folder / f"drops{count}.csv"
    write_csv(path, simulate_drops(Truth(**TRUTH), count, 4, rate=500.0))
    return load_tracks(path, sides=4, circumradius=RADIUS)


@pytest.fixture(scope="module")
def tracks(tmp_path_factory):
    return trackset(tmp_path_factory.mktemp("split"), 20)


def test_the_sets_are_the_files_split_and_every_usable_track_is_in_one(tracks):
    ready = splitting.split_tracks(tracks, CFG, 0.3, seed=2)
    select_set, confirm_set = tracks.split(0.3, 2)
    assert [t.traj for t in ready.select_set.tracks] == [t.traj for t in select_set.tracks]
    assert [t.traj for t in ready.confirm_set.tracks] == [t.traj for t in confirm_set.tracks]
    chosen, held = {p.traj for p in ready.select}, {p.traj for p in ready.confirm}
    assert not chosen & held and len(chosen) >= splitting.MIN_TRACKS and held
    assert chosen <= {t.traj for t in select_set.tracks}
    assert ready.seg_select.tracks == len(ready.select) and ready.seg_confirm.count == sum(len(p.flights) for p in ready.confirm)
    table, noise, sigma = tracking_noise(tracks, CFG)
    assert ready.table == table and ready.noise == noise and np.array_equal(ready.sigma, sigma)
    other = splitting.split_tracks(tracks, CFG, 0.3, seed=3)
    assert {p.traj for p in other.confirm} != held  # the seed chooses the held-out tracks


def test_too_few_tracks_is_one_line_naming_the_sets(tmp_path):
    few = trackset(tmp_path, 9)
    with pytest.raises(DiceSweepError) as error:
        splitting.split_tracks(few, CFG, roles=("fitting", "scoring"))
    message = str(error.value)
    assert "fitting and" in message and "scoring tracks" in message and f"at least {splitting.MIN_TRACKS} and 1" in message
    assert "9 tracks in the file" in message and "\n" not in message


def test_folds_are_balanced_and_fixed_by_the_trajectory_ids(tracks):
    prepared = splitting.split_tracks(tracks, CFG).select
    fold = splitting.assign_folds(prepared, 5, seed=0)
    counts = np.bincount(fold, minlength=5)
    assert counts.max() - counts.min() <= 1 and counts.sum() == len(prepared)
    np.testing.assert_array_equal(splitting.assign_folds(list(reversed(prepared)), 5, seed=0), fold[::-1])
    assert not np.array_equal(splitting.assign_folds(prepared, 5, seed=1), fold)


def test_the_fit_context_names_the_die_and_the_split():
    assert splitting.fit_context(CFG, 0.3, 7) == {"die": {"sides": 4, "circumradius": RADIUS},
                                                  "split": {"confirm_fraction": 0.3, "seed": 7}}
