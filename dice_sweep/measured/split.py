"""The tracks a fit uses: the tracking noise measured, the tracks split into a selection and a
confirmation set, each cut into segments, and the selection tracks' folds.

``fit`` and ``diagnose`` both start here (:func:`split_tracks`): the split is fixed by a hash of
each trajectory id and the seed (:meth:`dice_sweep.measured.tracks.TrackSet.split`), so a
``forecast`` from either command's JSON scores the same confirmation tracks (:func:`fit_context`).
"""

import math
from dataclasses import dataclass

import numpy as np

from dice_sweep.errors import DiceSweepError
from dice_sweep.measured import fit as shooting
from dice_sweep.measured.noise import tracking_noise
from dice_sweep.measured.tracks import TrackSet, split_hash

CONFIRM_FRACTION = 0.3
MIN_TRACKS = 8  # fewer usable selection tracks cannot test anything


@dataclass
class Split:
    """The tracks of one file made ready for a fit (:func:`split_tracks`)."""

    table: float  # m, the table's height in the file
    noise: dict  # :func:`dice_sweep.measured.noise.noise_floor`'s dict
    sigma: np.ndarray  # sigmas of x, y (m) and phi (rad)
    select_set: TrackSet
    confirm_set: TrackSet
    select: list  # PreparedTrack of the selection tracks with a usable first flight
    confirm: list  # ... and of the confirmation tracks
    seg_select: shooting.Segments
    seg_confirm: shooting.Segments


def split_tracks(trackset, cfg, confirm_fraction=CONFIRM_FRACTION, seed=0, *, roles=("selection", "confirmation")):
    """Measure the tracking noise, split the tracks, prepare and segment both sets.

    Parameters
    ----------
    trackset : TrackSet
        The tracks of one file.
    cfg : Config
        The die (its sides, circumradius and g).
    confirm_fraction : float
        Share of the tracks held out for confirmation, in [0, 1].
    seed : int
        Changes which tracks are held out.
    roles : (str, str)
        What the two sets are called in the error message (``fit`` fits and scores).

    Returns
    -------
    Split

    Raises
    ------
    DiceSweepError
        When fewer than MIN_TRACKS selection tracks, or no confirmation track, have a first
        free flight of ``fit.MIN_FLIGHT_FRAMES`` frames or more.
    """
    table, noise, sigma = tracking_noise(trackset, cfg)
    select_set, confirm_set = trackset.split(confirm_fraction, seed)
    select = shooting.prepare_tracks(select_set, cfg, noise=sigma, table=table)
    confirm = shooting.prepare_tracks(confirm_set, cfg, noise=sigma, table=table)
    if len(select) < MIN_TRACKS or not confirm:
        raise DiceSweepError(
            f"{trackset.path}: tracks: {len(select)} {roles[0]} and {len(confirm)} {roles[1]} tracks have a first free flight of "
            f"{shooting.MIN_FLIGHT_FRAMES} frames or more (allowed: at least {MIN_TRACKS} and 1; {len(trackset.tracks)} tracks in the file)"
        )
    return Split(table, noise, sigma, select_set, confirm_set, select, confirm,
                 shooting.Segments(select, cfg.world.g), shooting.Segments(confirm, cfg.world.g))


CROSS_FOLDS = 2  # cross-fitting folds of diagnose (more when the tracks are too few for halves)
MAX_CROSS_FOLDS = 5


@dataclass
class CrossFit:
    """All usable tracks of one file, in folds for cross-fitting (:func:`cross_fit_tracks`):
    fold k's model is chosen and fitted on the other folds' tracks and predicts fold k's."""

    table: float  # m, the table's height in the file
    noise: dict  # :func:`dice_sweep.measured.noise.noise_floor`'s dict
    sigma: np.ndarray  # sigmas of x, y (m) and phi (rad)
    trackset: TrackSet
    prepared: list  # PreparedTrack of every track with a usable first flight
    segments: shooting.Segments  # of all of them
    fold: np.ndarray  # fold of each prepared track
    folds: int
    g: float  # m/s^2, the config's (the segments' ballistic guesses)
    file_halves: bool = False  # the folds are TrackSet.split(0.5, seed)'s halves, fold 0 held out

    def part(self, k):
        """Fold k as (training prepared tracks, their Segments, their TrackSet, bool mask of the
        held-out tracks (over ``prepared``), the held-out tracks' Segments)."""
        test = self.fold == k
        train = [p for p, held in zip(self.prepared, test) if not held]
        held = [p for p, h in zip(self.prepared, test) if h]
        g = self.g
        return (train, shooting.Segments(train, g), self.trackset.with_trajs(p.traj for p in train), test,
                shooting.Segments(held, g))


def cross_fit_folds(count, folds=CROSS_FOLDS):
    """Folds for ``count`` tracks: ``folds``, or more when the training part of a fold would
    hold fewer than MIN_TRACKS tracks; None when even MAX_CROSS_FOLDS folds leave too few."""
    k = folds
    while k <= MAX_CROSS_FOLDS:
        if count - math.ceil(count / k) >= MIN_TRACKS:
            return k
        k += 1
    return None


def cross_fit_tracks(trackset, cfg, seed=0, folds=CROSS_FOLDS):
    """Measure the tracking noise, prepare every track and put the usable ones in folds
    (balanced, by a hash of the trajectory id and the seed: :func:`assign_folds`).

    Raises
    ------
    DiceSweepError
        When too few tracks have a first free flight of ``fit.MIN_FLIGHT_FRAMES`` frames for
        every fold's training part to hold MIN_TRACKS tracks.
    """
    table, noise, sigma = tracking_noise(trackset, cfg)
    prepared = shooting.prepare_tracks(trackset, cfg, noise=sigma, table=table)
    count = cross_fit_folds(len(prepared), folds)
    if count is None:
        least = next(n for n in range(MIN_TRACKS, 10 * MIN_TRACKS) if cross_fit_folds(n, folds))
        raise DiceSweepError(
            f"{trackset.path}: tracks: {len(prepared)} tracks have a first free flight of {shooting.MIN_FLIGHT_FRAMES} frames or more "
            f"(allowed: at least {least}, so that every cross-fitting fold is chosen on {MIN_TRACKS} or more; "
            f"{len(trackset.tracks)} tracks in the file)")
    file_halves = False
    if count == 2:
        # halves as TrackSet.split(0.5, seed) makes them, its held-out half fold 0: a
        # ``forecast`` of diagnose's held_out_model (fold 0's, chosen on fold 1) scores the
        # tracks that model never saw; balanced halves when the unusable tracks leave a side short
        held = {track.traj for track in trackset.split(0.5, seed)[1].tracks}
        fold = np.array([0 if p.traj in held else 1 for p in prepared], dtype=np.int64)
        file_halves = min(int(np.sum(fold == 0)), int(np.sum(fold == 1))) >= MIN_TRACKS
    if not file_halves:
        fold = assign_folds(prepared, count, f"cross:{seed}")
    return CrossFit(table, noise, sigma, trackset, prepared, shooting.Segments(prepared, cfg.world.g), fold, count, cfg.world.g,
                    file_halves)


def assign_folds(prepared, count, seed):
    """Fold index (0..count-1) of each prepared track, balanced, fixed by the trajectory ids."""
    order = sorted(range(len(prepared)), key=lambda i: split_hash(f"fold:{seed}", prepared[i].traj))
    fold = np.zeros(len(prepared), dtype=np.int64)
    for rank, i in enumerate(order):
        fold[i] = rank % count
    return fold


def fit_context(cfg, confirm_fraction, seed):
    """The die and the split of a fit, for its JSON (``forecast`` checks the die and scores
    the same confirmation tracks)."""
    return {"die": {"sides": cfg.die.sides, "circumradius": cfg.die.circumradius},
            "split": {"confirm_fraction": confirm_fraction, "seed": seed}}
