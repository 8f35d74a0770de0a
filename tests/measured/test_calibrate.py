"""calibrate: the paper's coefficients from drops of the paper model, the corner-impulse ones
from drops of the rigid model, glitches kept out, the command line, and the real drops."""

import json
import math

import numpy as np
import pytest
from matplotlib.colors import to_rgb

from dice_sweep import plotting
from dice_sweep.measured.calibrate import COEFFICIENTS, calibrate, summarise
from dice_sweep.measured.impacts import lowest_height
from dice_sweep.measured.tracks import TrackSet, load_tracks
from tests.helpers import figure_pixels, invoke, near, png_size, read_png
from tests.measured import drops
from tests.measured.test_tracks import real_tracks

DROPS = 16
PAPER = {"model": "paper", "beta_normal": 0.4, "beta_tangential": -0.2}
RIGID = {"model": "rigid", "beta_normal": 0.5, "beta_tangential": -0.3}  # friction inf
# Medians of 16 first impacts at 250 Hz with 0.2 mm and 0.3 deg of noise: one impact's normal
# coefficient is good to about 0.01 and its tangential one to about 0.05 (the spin after the
# impact comes from five noisy angles).
NORMAL_TOLERANCE = 0.02
TANGENTIAL_TOLERANCE = 0.04


def landing_states(count, seed):
    """Clean single-corner landings: no spin, a side 25-40 deg off flat, drifting in -x.

    The paper's law then holds at the first impact (the touching corner leaves the table), and
    the rigid law's impulse gains no energy, so neither model's fallback changes the impact.
    """
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [
            rng.uniform(-0.05, 0.05, count),
            rng.uniform(0.12, 0.16, count),
            rng.choice([-1.0, 1.0], count) * np.radians(rng.uniform(5.0, 20.0, count)),  # corner 0 near straight down
            rng.uniform(-0.6, -0.4, count),
            rng.uniform(-2.0, -1.8, count),
            np.zeros(count),
        ]
    )


def calibrated(tmp_path, law, *, sign, glitch_before_impact=None):
    """Simulate, write in a file convention of ``sign``, load (auto) and calibrate."""
    cfg = drops.die_config(**law)
    times, truth = drops.simulate(cfg, landing_states(DROPS, seed=5))
    glitches = None
    if glitch_before_impact is not None:  # frames before each drop's first contact
        first_contact = np.argmax(lowest_height(4, drops.RADIUS, truth[:, :, 1], truth[:, :, 2]) < 1e-3, axis=1)
        glitches = {drop: int(frame) - glitch_before_impact for drop, frame in enumerate(first_contact)}
    file_tracks = drops.to_file(times, truth, seed=6, sign=sign, glitches=glitches)
    trackset = load_tracks(drops.write_csv(tmp_path / "drops.csv", file_tracks), sides=4, circumradius=drops.RADIUS, angle="auto")
    return trackset, calibrate(trackset, cfg)


def first_impacts(result, name):
    values = [row[name] for row in result.rows if row["first"]]
    assert len(values) == DROPS and all(row["clean"] for row in result.rows if row["first"])
    return np.array(values, dtype=float)


def test_paper_model_coefficients_come_back(tmp_path):
    trackset, result = calibrated(tmp_path, PAPER, sign=-1)
    assert trackset.angle_sign == -1
    assert np.median(first_impacts(result, "beta_normal")) == pytest.approx(PAPER["beta_normal"], abs=NORMAL_TOLERANCE)
    assert np.median(first_impacts(result, "beta_tangential")) == pytest.approx(PAPER["beta_tangential"], abs=TANGENTIAL_TOLERANCE)
    assert result.summary["first"]["beta_normal"]["n"] == DROPS


def test_rigid_model_corner_coefficients_come_back(tmp_path):
    trackset, result = calibrated(tmp_path, RIGID, sign=1)
    assert trackset.angle_sign == 1
    assert np.median(first_impacts(result, "corner_normal")) == pytest.approx(RIGID["beta_normal"], abs=NORMAL_TOLERANCE)
    assert np.median(first_impacts(result, "corner_tangential")) == pytest.approx(RIGID["beta_tangential"], abs=TANGENTIAL_TOLERANCE)
    # an impulse through the corner: the angular momentum balance holds
    assert result.summary["first"]["balance"]["median"] == pytest.approx(1.0, abs=0.15)


def test_a_glitch_just_before_the_impact_is_left_out(tmp_path):
    trackset, result = calibrated(tmp_path, PAPER, sign=-1, glitch_before_impact=2)
    assert trackset.glitch_count == DROPS
    normal = first_impacts(result, "beta_normal")
    assert np.all(np.abs(normal - PAPER["beta_normal"]) < 3 * NORMAL_TOLERANCE)


def test_summary_counts_robust_outliers():
    stats = summarise([0.40, 0.41, 0.39, 0.40, 0.42, 0.38, 0.40, 5.0])
    assert stats["n"] == 8 and stats["outliers"] == 1 and stats["median_inliers"] == pytest.approx(0.40)
    assert summarise([])["n"] == 0


def test_calibrate_command_writes_json_and_png(tmp_path):
    cfg = drops.die_config(**PAPER)
    times, truth = drops.simulate(cfg, landing_states(4, seed=7))
    data = drops.write_csv(tmp_path / "drops.csv.gz", drops.to_file(times, truth, seed=8))
    config = tmp_path / "die.toml"
    config.write_text(f"[die]\nsides = 4\ncircumradius = {drops.RADIUS!r}\n")
    out_json, out_png = tmp_path / "cal.json", tmp_path / "cal.png"
    result = invoke("calibrate", data, "--config", config, "--angle", "auto", "--json", out_json, "--png", out_png)
    assert result.exit_code == 0, result.output
    assert "beta_normal" in result.output
    report = json.loads(out_json.read_text())
    assert len(report["impacts"]) >= 4 and report["summary"]["first"]["beta_normal"]["n"] == 4
    # the picture at its size (120 dpi), one panel a coefficient in a 2 x 2 grid, each with the
    # first impacts' bars (tab:blue at alpha 0.6 on white; more than the legend's swatch) and
    # their median, a dashed tab:blue line down the panel
    assert png_size(out_png) == figure_pixels(plotting.CALIBRATION_FIGSIZE, 120)
    image = read_png(out_png)
    half_height, half_width = image.shape[0] // 2, image.shape[1] // 2
    bars = 1 - 0.6 * (1 - np.array(to_rgb("tab:blue")))
    assert len(COEFFICIENTS) == 4
    for row in (0, 1):
        for column in (0, 1):
            panel = image[row * half_height : (row + 1) * half_height, column * half_width : (column + 1) * half_width]
            assert near(panel, bars).sum() > 1000, (row, column)
            # a 1-point line is 1.7 pixels wide at 120 dpi: antialiased, so a wider tolerance
            assert near(panel, to_rgb("tab:blue"), tol=0.2).sum(axis=0).max() > 0.3 * half_height, (row, column)
    bad = invoke("calibrate", config, "--config", config)
    assert bad.exit_code == 2 and bad.output.count("\n") == 1 and "column" in bad.output
    no_rate = invoke("calibrate", data, "--config", config, "--rate", "-5")
    assert no_rate.exit_code == 2 and "rate" in no_rate.output
    help_text = invoke("calibrate", "--help").output
    assert help_text.rstrip().splitlines()[-1].strip().startswith("dice-sweep calibrate")  # its example, last


def test_real_drops_subset_gives_finite_coefficients():
    trackset = real_tracks()
    subset = TrackSet(trackset.path, trackset.tracks[:40], trackset.rate, trackset.angle_sign, trackset.angle_offset,
                      trackset.angle_note, 0, 0)
    result = calibrate(subset, drops.die_config())
    first = result.summary["first"]
    assert first["beta_normal"]["n"] >= 15 and 0.2 < first["beta_normal"]["median"] < 0.6
    assert 0.3 < result.summary["first_corner"]["corner_normal"]["median"] < 0.6
    assert all(math.isfinite(first[name]["median"]) for name in ("beta_tangential", "corner_tangential"))
