"""One roll from a config: the result, its event tallies, and its path at any time."""

from dataclasses import dataclass

import numpy as np

from dice_sweep import engine
from dice_sweep.physics import pack_params
from dice_sweep.physics.kernel import roll_one, sample_records
from dice_sweep.physics.layout import COUNT_COLUMNS, REC_WIDTH, ROLL_RECORDS, STATE_COLUMNS, STATUS_NAMES


def initial_state(cfg):
    """The config's initial state as float64[6] in STATE_COLUMNS order (SI): the start of a
    roll, and the unswept values of every start of a sweep."""
    return np.array([getattr(cfg.initial, name) for name in STATE_COLUMNS], dtype=np.float64)


@dataclass(frozen=True)
class RollReport:
    """Result of one roll.

    Attributes
    ----------
    outcome : int
        Side 0..n-1 that the die comes to rest on, -1 when undecided.
    status : int
        Index into ``dice_sweep.physics.STATUS_NAMES``; 0 means decided.
    t_decided : float
        Simulated time (s) at which the side was decided; NaN when undecided.
    t_end : float
        Simulated time (s) at which the simulation stopped.
    counts : dict
        Event tallies: impacts, wall_impacts, corner_fallbacks (the paper's law undefined,
        impulse at the corner used), pivots (sustained-contact phases), energy_clips,
        multi_contacts (impacts of two contacts at once).
    records : numpy.ndarray
        Segment records (see dice_sweep.physics.kernel), to re-create the path.
    """

    outcome: int
    status: int
    t_decided: float
    t_end: float
    counts: dict
    records: np.ndarray

    @property
    def status_name(self):
        return STATUS_NAMES[self.status]

    @property
    def impacts(self):
        return self.counts["impacts"]

    def to_dict(self):
        """JSON-ready summary (no records); a time that is not a finite number is null (JSON
        has no NaN)."""
        return {
            "outcome": self.outcome,
            "status": self.status_name,
            "status_code": self.status,
            "impacts": self.impacts,
            "t_decided": self.t_decided if np.isfinite(self.t_decided) else None,
            "t_end": self.t_end if np.isfinite(self.t_end) else None,
            **{k: v for k, v in self.counts.items() if k != "impacts"},
        }


def roll_config(cfg, state=None):
    """Simulate the roll of a validated config (its [initial] state unless ``state`` given)."""
    fpar, ipar = pack_params(cfg)
    rec = np.zeros((ROLL_RECORDS, REC_WIDTH))
    counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
    s0 = initial_state(cfg) if state is None else np.asarray(state, dtype=float)
    args = (fpar, ipar, s0, rec, counts)
    outcome, status, t_decided, t_end, n_rec = engine.run(roll_one, engine.call_engine(roll_one, args), *args)
    return RollReport(
        outcome=int(outcome),
        status=int(status),
        t_decided=float(t_decided),
        t_end=float(t_end),
        counts={name: int(c) for name, c in zip(COUNT_COLUMNS, counts)},
        records=rec[:n_rec].copy(),
    )


def sample_path(cfg, report, times):
    """State (x, y, phi, vx, vy, omega) of the centre at ``times`` (s) during the roll.

    Times before 0 or after ``report.t_end`` are clipped to the simulated span.
    """
    fpar, ipar = pack_params(cfg)
    t = np.clip(np.sort(np.asarray(times, dtype=float)), 0.0, report.t_end)
    out = np.zeros((t.size, 6))
    rec = report.records
    args = (fpar, ipar, rec, rec.shape[0], t, out)
    engine.run(sample_records, engine.call_engine(sample_records, args), *args)
    return out
