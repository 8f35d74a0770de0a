"""The pieces of diagnose's cross-fitting (issue 30, items 1-2): parts of a set of segments,
the folds, the selection rule against heavy tails, the union of the folds' effects, and the
halves forecast holds out. The cause-or-stand-in test is in tests/measured/test_consistency.py;
the loop itself runs in tests/measured/test_diagnose.py."""

import math

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.measured import consistency
from dice_sweep.measured import diagnose as loop
from dice_sweep.measured import fit as shooting
from dice_sweep.measured.split import MIN_TRACKS, cross_fit_folds, cross_fit_tracks
from tests.measured.cases import DECLARED_RIGID, truth_tracks

CFG = parse_config(DECLARED_RIGID)


@pytest.fixture(scope="module")
def tracks(tmp_path_factory):
    return truth_tracks(tmp_path_factory.mktemp("crossfit"), 20, 3)


def test_a_subset_of_segments_is_the_segments_of_its_tracks(tracks):
    cross = cross_fit_tracks(tracks, CFG, seed=1)
    whole = cross.segments
    for k in range(cross.folds):
        train, seg_train, train_set, test, seg_test = cross.part(k)
        part = whole.subset(test[whole.track])
        assert {p.traj for p in train} == {t.traj for t in train_set.tracks}
        assert seg_train.tracks + seg_test.tracks == whole.tracks
        for name in ("count", "tracks"):
            assert getattr(part, name) == getattr(seg_test, name)
        for name in ("track", "starts", "times", "measured", "predicted", "track_rows", "segment_rows", "track_starts",
                     "track_segment_starts", "guess"):
            assert np.array_equal(getattr(part, name), getattr(seg_test, name)), name
        # the frames keep the whole set's numbering: they are the rows' frames in it
        assert np.array_equal(part.frame_rows, whole.frame_rows[test[whole.track_rows]])


def test_the_first_flights_are_a_part_too(tracks):
    whole = cross_fit_tracks(tracks, CFG).segments
    first = consistency.flight_index(whole) == 0
    assert first.sum() == whole.tracks
    part = whole.subset(first)
    assert part.count == part.tracks == whole.tracks and np.array_equal(part.track, np.arange(whole.tracks))
    later = whole.subset(~first)
    assert later.count == whole.count - whole.tracks


def test_folds_are_halves_unless_the_tracks_are_few():
    assert cross_fit_folds(90) == 2 and cross_fit_folds(16) == 2
    assert cross_fit_folds(14) == 3  # halves of 7 would choose on fewer than MIN_TRACKS
    for count in range(10, 40):
        k = cross_fit_folds(count)
        assert count - math.ceil(count / k) >= MIN_TRACKS
    assert cross_fit_folds(9) is None


def _result(e_current, e_cand, floor=1.0):
    worse, better = loop.marked_tracks(np.array(e_current), np.array(e_cand), floor)
    return {"significant": True, "null_excluded": True, "excess_share": 0.5, "at_bound": [],
            "median_falls": bool(np.median(e_cand) < np.median(e_current)),
            "rms_falls": loop.rms_falls(np.array(e_current), np.array(e_cand)), "worse_tracks": worse, "better_tracks": better,
            "worse_within_share": bool(worse <= loop.MAX_WORSE_SHARE * (worse + better))}


def test_heavy_tails_cannot_pass():
    current = np.full(20, 3.0)
    # the median falls, a few tracks blow up: the RMS rises (the friction, 5.7 -> 19.4 mm)
    blown = np.r_[np.full(17, 2.0), [30.0, 30.0, 30.0]]
    assert not loop.candidate_passes(_result(current, blown))
    # the RMS falls, the typical track gets worse
    lifted = np.r_[np.full(12, 3.2), np.full(8, 1.0)]
    assert shooting.rms(lifted) < shooting.rms(current) and not loop.candidate_passes(_result(current, lifted))
    # both fall, but 5 of the 16 tracks that move by more than half the floor get worse
    mixed = np.r_[np.full(11, 1.0), np.full(5, 4.2), np.full(4, 3.0)]
    assert shooting.rms(mixed) < shooting.rms(current) and np.median(mixed) < 3.0
    assert not loop.candidate_passes(_result(current, mixed))
    # a real gain: most tracks better, one worse
    gain = np.r_[np.full(18, 1.5), [3.6], [3.0]]
    assert loop.candidate_passes(_result(current, gain))
    # ... even when that one track (a prediction across a near-flat landing) lifts the RMS over all
    chaotic = np.r_[np.full(19, 1.5), [12.0]]
    assert shooting.rms(chaotic) > shooting.rms(current) and loop.candidate_passes(_result(current, chaotic))
    # two such tracks decide it
    assert not loop.candidate_passes(_result(current, np.r_[np.full(18, 1.5), [12.0, 12.0]]))


def test_the_named_model_takes_each_folds_effects_once():
    def model(*effects):
        return shooting.FitResult(shooting.ModelSpec.of(CFG, effects), {}, np.zeros((0, 6)), (), 0.0, 0, True, {})

    assert loop.named_effects([model("air_drag"), model("com_offset", "air_drag")]) == ["air_drag", "com_offset"]
    # indistinguishable effects are named once; two friction rules never together (the one more folds chose)
    assert loop.named_effects([model("gravity"), model("time_scale")]) == ["gravity"]
    assert loop.named_effects([model("sliding_friction"), model("exact_coulomb"), model("exact_coulomb")]) == ["exact_coulomb"]






def test_a_verdict_with_stand_ins_alone_names_no_cause():
    assert loop.verdict_of(1.0, 1.0, ["air_drag"], []) == "explained"
    assert loop.verdict_of(1.0, 1.0, ["table_offset"], ["table_offset"]) == "unexplained"  # within the floor, but by a stand-in
    assert loop.verdict_of(1.0, 1.0, ["air_drag", "table_offset"], ["table_offset"]) == "improved"
    assert loop.verdict_of(2.0, 1.0, [], []) == "unexplained"
    assert loop.verdict_of(2.0, 1.0, ["air_drag"], []) == "improved"




def test_halves_are_the_split_forecast_holds_out(tracks):
    """With two folds, fold 0 is the held-out half of TrackSet.split(0.5, seed): a forecast of
    diagnose's held_out_model (chosen on fold 1) scores tracks that model never saw."""
    cross = cross_fit_tracks(tracks, CFG, seed=4)
    assert cross.folds == 2 and cross.file_halves
    held = {t.traj for t in tracks.split(0.5, 4)[1].tracks}
    assert {p.traj for p, k in zip(cross.prepared, cross.fold) if k == 0} == held & {p.traj for p in cross.prepared}


def test_forecast_reads_the_held_out_model_of_a_cross_fitted_diagnose():
    from dice_sweep.measured.forecast import parse_fit

    params = {"beta_normal": {"value": 0.41, "ci95": [0.40, 0.42]}, "beta_tangential": {"value": 0.0, "ci95": [-0.01, 0.01]},
              "friction": {"value": 0.3, "ci95": [0.29, 0.31]}}
    held = {name: dict(entry, value=entry["value"] + 0.001) for name, entry in params.items()}
    data = {"effects_added": [], "after": {"params": params, "effects": ["corner_impulse", "coulomb_friction"]},
            "bootstrap_draws": {"names": list(params), "values": [[0.41, 0.0, 0.3]]}, "split": {"confirm_fraction": 0.3, "seed": 0},
            "held_out_model": {"effects": ["corner_impulse", "coulomb_friction"], "params": held,
                               "bootstrap_draws": {"names": list(params), "values": [[0.411, 0.001, 0.301], [0.412, 0.0, 0.3]]},
                               "split": {"confirm_fraction": 0.5, "seed": 7}}}
    source = parse_fit(data, "r.json", CFG, 0.3, 0)
    assert source.params == {name: entry["value"] for name, entry in held.items()}
    assert (source.confirm_fraction, source.seed) == (0.5, 7) and source.draws.shape == (2, 3)


def test_candidates_that_fit_alike_give_the_simplest():
    rng = np.random.default_rng(3)
    errors = rng.uniform(1e-4, 5e-4, 40)

    def cand(effects, share, errors=errors):
        return {"effect": "+".join(effects), "effects": list(effects), "excess_share": share, "errors": errors}

    pool = ["corner_impulse", "air_drag", "sliding_friction", "exact_coulomb"]
    # with an infinite friction the three contact rules fit alike, the refits' rounding deciding the largest share
    jitter = errors * (1 + 1e-3 * rng.standard_normal(40))
    accepted = [cand(["exact_coulomb"], 1.0004), cand(["sliding_friction"], 0.9999, jitter), cand(["corner_impulse"], 0.9986, jitter[::-1])]
    best, alike = loop.best_candidate(accepted, pool)
    assert best["effect"] == "corner_impulse" and sorted(alike) == ["exact_coulomb", "sliding_friction"]
    # a share clearly smaller is not alike, and the largest share wins
    best, alike = loop.best_candidate([cand(["air_drag"], 0.9), cand(["exact_coulomb"], 0.95)], pool)
    assert best["effect"] == "exact_coulomb" and alike == []
    # nor is one whose tracks are systematically apart, however close the shares
    best, alike = loop.best_candidate([cand(["corner_impulse"], 0.949, errors * 1.05), cand(["exact_coulomb"], 0.95)], pool)
    assert best["effect"] == "exact_coulomb" and alike == []
    # a pair alike a single effect gives the single one
    best, _ = loop.best_candidate([cand(["air_drag", "corner_impulse"], 0.99), cand(["exact_coulomb"], 0.985, jitter)], pool)
    assert best["effect"] == "exact_coulomb"
