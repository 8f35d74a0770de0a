"""Tests of dice_sweep.physics.layout: the kernels' data layout is consistent (names at their
codes, record columns that tile a row) and is the layout the kernel writes (a roll's records,
its counters and its status read through these names)."""

import math

import numpy as np
import pytest

from dice_sweep.chaos import measures
from dice_sweep.config import CONTACT_MODELS, INTEGRATOR_METHODS, default_config
from dice_sweep.effects import FRICTION_RULES, RESTITUTION_LAWS
from dice_sweep.physics import layout
from dice_sweep.physics.layout import (
    C_IMPACTS,
    C_WALL,
    COUNT_COLUMNS,
    EVENT_IMPACT,
    EVENT_START,
    REC_CORNER,
    REC_ENERGY,
    REC_EVENT,
    REC_KIND,
    REC_STATE,
    REC_T,
    REC_WIDTH,
    SEG_FLIGHT,
    STATE_COLUMNS,
    STATUS_NAMES,
    UNDECIDED,
)
from dice_sweep.roll import initial_state
from tests.physics.conftest import TABLE1_RADIUS, make_params, run_one


def test_status_names_and_count_columns_sit_at_their_codes():
    for name in STATUS_NAMES:
        assert STATUS_NAMES.index(name) == getattr(layout, f"STATUS_{name.upper()}")
    assert [COUNT_COLUMNS[getattr(layout, code)] for code in ("C_IMPACTS", "C_WALL", "C_FALLBACK", "C_PIVOTS", "C_CLIPS", "C_MULTI")] == [
        "impacts", "wall_impacts", "corner_fallbacks", "pivots", "energy_clips", "multi_contacts"]
    assert len(set(COUNT_COLUMNS)) == len(COUNT_COLUMNS)


def test_record_columns_tile_a_row_with_the_state_in_six():
    single = {name: getattr(layout, name) for name in dir(layout) if name.startswith("REC_") and name not in ("REC_STATE", "REC_WIDTH")}
    columns = sorted([*single.values(), *range(REC_STATE, REC_STATE + 6)])
    assert columns == list(range(REC_WIDTH))  # every column once, none past the width
    segments = [getattr(layout, name) for name in dir(layout) if name.startswith("SEG_")]
    assert len(set(segments)) == len(segments)


def test_codes_of_the_configs_choices_are_their_indices():
    assert list(layout.MODELS) == list(CONTACT_MODELS) and list(layout.MODELS.values()) == list(range(len(CONTACT_MODELS)))
    assert list(layout.METHODS) == list(INTEGRATOR_METHODS)
    assert (layout.FRICTION_RULE_AIMED, layout.FRICTION_RULE_SLIDING, layout.FRICTION_RULE_EXACT) == (
        FRICTION_RULES.index("aimed"), FRICTION_RULES.index("sliding"), FRICTION_RULES.index("exact"))
    assert (layout.RESTITUTION_NEWTON, layout.RESTITUTION_ENERGETIC) == (0, 1) == (
        RESTITUTION_LAWS.index("newton"), RESTITUTION_LAWS.index("energetic"))
    assert UNDECIDED == measures.UNDECIDED == -1 and layout.PATH_CUT not in (UNDECIDED, *range(0, 100))


def test_the_initial_state_is_in_state_column_order():
    cfg = default_config()
    values = dict(zip(STATE_COLUMNS, (0.001, 0.2, 0.3, -0.4, 0.5, 6.0)))
    np.testing.assert_array_equal(initial_state(cfg.with_initial(**values)), list(values.values()))


def test_a_roll_is_written_in_this_layout():
    """A square dropped corner first from 0.1 m, straight down, at beta_normal 1/2: its records
    start with the flight from the start state; each impact starts a flight straight up at half
    the speed it came in with, each row's energy that of its state; its counters say impacts on
    the table, none on a wall; balanced on its corner, it ends undecided with that status."""
    g = 9.81
    start = [0.0, 0.1, -math.pi / 2, 0.0, 0.0, 0.0]
    outcome, status, _, _, rec, counts = run_one(make_params(beta_n=0.5), start)
    assert (rec[0, REC_KIND], rec[0, REC_EVENT], rec[0, REC_T], rec[0, REC_CORNER]) == (SEG_FLIGHT, EVENT_START, 0.0, -1)
    np.testing.assert_array_equal(rec[0, REC_STATE : REC_STATE + 6], start)
    t_hit = math.sqrt(2 * (0.1 - TABLE1_RADIUS) / g)
    assert rec[1, REC_T] == pytest.approx(t_hit, rel=1e-12)
    assert (rec[1, REC_KIND], rec[1, REC_EVENT]) == (SEG_FLIGHT, EVENT_IMPACT)
    assert rec[1, REC_STATE + 1] == pytest.approx(TABLE1_RADIUS, rel=1e-12)  # the centre over the corner
    assert rec[1, REC_STATE + 4] == pytest.approx(0.5 * g * t_hit, rel=1e-12)  # up at half the speed
    x, y, phi, vx, vy, omega = rec[:, REC_STATE : REC_STATE + 6].T
    np.testing.assert_allclose(rec[:, REC_ENERGY], g * y + 0.5 * (vx * vx + vy * vy) + 0.5 * omega * omega * TABLE1_RADIUS**2 / 3,
                               rtol=1e-12)
    assert counts[C_IMPACTS] > 3 and counts[C_WALL] == 0
    assert (outcome, status) == (UNDECIDED, layout.STATUS_BALANCED)
