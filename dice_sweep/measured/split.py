"""The tracks a fit uses: the tracking noise measured, the tracks split into a selection and a
confirmation set, each cut into segments, and the selection tracks' folds.

``fit`` and ``diagnose`` both start here (:func:`split_tracks`): the split is fixed by a hash of
each trajectory id and the seed (:meth:`dice_sweep.measured.tracks.TrackSet.split`), so a
``forecast`` from either command's JSON scores the same confirmation tracks (:func:`fit_context`).
"""

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
