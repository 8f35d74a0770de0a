"""Tests of dice_sweep.roll: a config's start in STATE_COLUMNS order, one roll of a config (its
report, from the [initial] state or a given one) and its path sampled from the records."""

import math

import numpy as np

from dice_sweep.config import parse_config
from dice_sweep.physics.layout import COUNT_COLUMNS, STATUS_NAMES
from dice_sweep.roll import initial_state, roll_config, sample_path

G = 9.81
CONFIG = "[die]\nsides = 4\n[initial]\ny0 = 0.2\nphi0 = -1.5707963267948966\nvx0 = 0.3\nomega0 = 0.0\n"  # corner first, drifting right


def test_initial_state_reads_the_configs_start():
    cfg = parse_config(CONFIG)
    np.testing.assert_array_equal(initial_state(cfg), [0.0, 0.2, -math.pi / 2, 0.3, 0.0, 0.0])
    assert initial_state(cfg).dtype == np.float64


def test_a_roll_reports_its_side_status_times_and_counts():
    cfg = parse_config(CONFIG)
    report = roll_config(cfg)
    assert report.status_name == STATUS_NAMES[report.status]
    assert list(report.counts) == list(COUNT_COLUMNS) and report.impacts == report.counts["impacts"] >= 1
    assert report.t_end >= report.t_decided > math.sqrt(2 * (0.2 - cfg.die.circumradius) / G)  # not before the first impact
    summary = report.to_dict()
    assert summary["outcome"] == report.outcome and summary["status"] == report.status_name
    assert summary["impacts"] == report.impacts and "records" not in summary
    assert {k: summary[k] for k in COUNT_COLUMNS if k != "impacts"} == {k: v for k, v in report.counts.items() if k != "impacts"}


def test_a_given_state_replaces_the_configs_start():
    cfg = parse_config(CONFIG)
    state = [0.0, 0.3, 0.1, 0.0, 0.0, 12.0]
    given = roll_config(cfg, state=state)
    same = roll_config(cfg.with_initial(y0=0.3, phi0=0.1, vx0=0.0, omega0=12.0))
    assert (given.outcome, given.t_decided, given.counts) == (same.outcome, same.t_decided, same.counts)
    np.testing.assert_array_equal(given.records, same.records)


def test_the_path_is_the_flight_in_closed_form_until_the_first_impact():
    cfg = parse_config(CONFIG)
    report = roll_config(cfg)
    t_hit = math.sqrt(2 * (0.2 - cfg.die.circumradius) / G)
    times = np.linspace(0.0, 0.95 * t_hit, 7)
    path = sample_path(cfg, report, times)
    expected = np.column_stack([0.3 * times, 0.2 - 0.5 * G * times**2, np.full(7, -math.pi / 2), np.full(7, 0.3), -G * times, np.zeros(7)])
    np.testing.assert_allclose(path, expected, rtol=0, atol=1e-12)


def test_times_outside_the_roll_are_clipped_and_sorted():
    cfg = parse_config(CONFIG)
    report = roll_config(cfg)
    path = sample_path(cfg, report, [report.t_end + 5.0, -1.0, 0.0])
    np.testing.assert_array_equal(path[0], path[1])  # -1 s and 0 s: the start
    np.testing.assert_array_equal(path[0], initial_state(cfg))
    np.testing.assert_array_equal(path[2], sample_path(cfg, report, [report.t_end])[0])  # later: the end
    radius = cfg.die.circumradius
    assert radius / math.sqrt(2) * (1 - 1e-12) <= path[2, 1] < radius  # decided: on the table, below the barrier


def test_a_time_that_is_not_a_number_is_null_in_the_json():
    """Issue 32: `roll --json` printed "t_end": NaN, which is not JSON."""
    import dataclasses
    import json

    report = roll_config(parse_config(CONFIG))
    assert json.loads(json.dumps(report.to_dict(), allow_nan=False))["t_end"] == report.t_end  # the control: a number
    broken = dataclasses.replace(report, t_end=math.nan, t_decided=math.inf)
    summary = json.loads(json.dumps(broken.to_dict(), allow_nan=False))
    assert summary["t_end"] is None and summary["t_decided"] is None
