"""dice_sweep.measured.noise: the tracking noise of a file, on drops of known noise from the
independent generator."""

import math

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured import noise
from dice_sweep.measured.tracks import load_tracks
from tests.measured.cases import DECLARED_RIGID, RADIUS, truth_tracks

SIGMA = (3e-4, 6e-3)  # m, rad


@pytest.fixture(scope="module")
def trackset(tmp_path_factory):
    return truth_tracks(tmp_path_factory.mktemp("noise"), 24, 3, noise=SIGMA)


def test_the_noise_floor_finds_the_trackers_sigmas(trackset):
    cfg = parse_config(DECLARED_RIGID)
    table, found, sigma = noise.tracking_noise(trackset, cfg)
    assert table == 0.0  # these drops end before rest: no table height measured
    np.testing.assert_array_equal(sigma, [found["sigma_x"], found["sigma_y"], found["sigma_phi"]])
    np.testing.assert_allclose(sigma, [SIGMA[0], SIGMA[0], SIGMA[1]], rtol=0.25)
    assert found["pose"] == pytest.approx(math.sqrt(sigma[0] ** 2 + sigma[1] ** 2 + (RADIUS * sigma[2]) ** 2), rel=1e-12)
    assert found["pose_ci95"][0] < found["pose"] < found["pose_ci95"][1] and found["tracks"] == 24
    assert noise.residual_sigmas(found, cfg) == (found["sigma_x"], found["sigma_y"], RADIUS * found["sigma_phi"])


def test_no_free_flight_is_a_one_line_error(tmp_path):
    path = tmp_path / "still.csv"
    path.write_text("traj,t,x,y,phi\n" + "".join(f"{k // 40 + 1},{(k % 40) * 0.002},0,0.021,0.785\n" for k in range(120)))
    with pytest.raises(DiceSweepError, match="no free flight long enough to measure the tracking noise"):
        noise.tracking_noise(load_tracks(path, sides=4, circumradius=RADIUS), parse_config(DECLARED_RIGID))


def test_the_table_height_is_the_median_rest_height(tmp_path):
    """Dice at rest 2 mm above the file's zero: the table is there (the apothem R cos(pi/4) up)."""
    apothem = RADIUS * math.cos(math.pi / 4)
    path = tmp_path / "rest.csv"
    path.write_text("traj,t,x,y,phi\n" + "".join(f"{k // 100 + 1},{(k % 100) * 0.002},0,{apothem + 0.002!r},{math.pi / 4!r}\n"
                                                 for k in range(300)))
    assert noise.table_height(load_tracks(path, sides=4, circumradius=RADIUS), parse_config(DECLARED_RIGID)) == pytest.approx(0.002, abs=1e-9)
