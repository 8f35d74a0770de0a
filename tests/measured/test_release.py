"""dice_sweep.measured.release: the final-state map of the release states, on drops whose side
is the model's own (so a drop's cell must mostly show the side it rested on)."""

from types import SimpleNamespace

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.measured import forecast as fc
from dice_sweep.measured.fit import kernel_config
from dice_sweep.measured.release import release_map
from tests.measured.cases import DECLARED_RIGID

CFG = parse_config(DECLARED_RIGID)
PARAMS = {"beta_normal": 0.4, "beta_tangential": 0.0, "friction": 0.3}
SOURCE = fc.FitSource("fit.json", "fit", (), PARAMS, tuple(PARAMS), None, np.zeros(3), "the truth", 0.3, 0, None, None)


@pytest.fixture(scope="module")
def run():
    """30 slow, low drops whose omega0 and phi0 vary most; each rests on the model's side."""
    rng = np.random.default_rng(4)
    count = 30
    states = np.column_stack([np.zeros(count), rng.normal(0.12, 1e-4, count), rng.uniform(0.2, 1.2, count),
                              rng.normal(-0.1, 1e-3, count), rng.normal(-0.5, 1e-3, count), rng.uniform(-6.0, 6.0, count)])
    sides, _ = fc.roll(kernel_config(CFG, SOURCE.spec(CFG), PARAMS), states)
    flights = [fc.FlightState(k + 1, states[k], np.eye(6) * 1e-8, 1.0, 10, 0.0) for k in range(count)]
    return SimpleNamespace(release=flights, observed={k + 1: int(sides[k]) for k in range(count)}, held_out_traj={1, 2, 3})


def test_the_map_is_over_the_two_values_that_vary_most_and_holds_the_drops(run):
    summary, picture = release_map(CFG, SOURCE, run, 32, workers=1)
    assert summary["axes"] == ["omega0", "phi0"] and summary["phi0_folded"] and summary["size"] == [32, 32]
    assert picture["outcome"].shape == (32, 32) and set(np.unique(picture["outcome"])) <= {-1, 0, 1, 2, 3}
    assert summary["drops"] == summary["drops_in_map"] == 30
    states = np.array([f.state for f in run.release])
    assert summary["fixed"]["vy0"] == pytest.approx(np.median(states[:, 4])) and set(summary["fixed"]) == {"x0", "y0", "vx0", "vy0"}
    # the drops rested on the model's side: their cells mostly show it; each drop's cell found
    # here as the nearest cell centre (rows are y, columns x)
    col = np.abs(picture["x"][None, :] - picture["drops_x"][:, None]).argmin(axis=1)
    row = np.abs(picture["y"][None, :] - picture["drops_y"][:, None]).argmin(axis=1)
    shown = picture["outcome"][row, col] == picture["drops_side"]
    assert summary["drops_side_as_map"] == pytest.approx(shown.mean()) and shown.mean() > 0.6
    assert picture["held_out"].sum() == 3 and picture["cfg"].grid.x.num == 32


def test_given_axes_are_used_as_given(run):
    summary, picture = release_map(CFG, SOURCE, run, 16, axes=("omega0", "y0"), workers=1)
    assert summary["axes"] == ["omega0", "y0"] and summary["axes_rule"] == "given by --map-axes" and not summary["phi0_folded"]
    assert picture["x_label"].startswith("omega0") and "phi0" in summary["fixed"]
