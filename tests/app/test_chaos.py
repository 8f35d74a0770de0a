"""Tests of dice_sweep.app.chaos: the measure and control commands, a sweep file in and
numbers, JSON, pictures and arrays out (the measures: tests/chaos/, the pictures' drawing:
tests/plotting/test_chaos.py)."""

import json
import math

import matplotlib
import numpy as np
import pytest

from dice_sweep import plotting
from dice_sweep.app.chaos import measure_file, read_complete_sweep, run_control, run_measure
from dice_sweep.chaos import basin_entropy, measure_map
from dice_sweep.config import load_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.storage import read_sweep
from tests.helpers import CONFIGS, figure_pixels, invoke, map_region, near, png_size, read_png, share, small_sweep

MAGMA, VIRIDIS = matplotlib.colormaps["magma"], matplotlib.colormaps["viridis"]


@pytest.fixture(scope="module")
def partial_file(tmp_path_factory):
    """fig08 at 16 x 16, half its tiles computed."""
    cfg = load_config(CONFIGS / "fig08.toml", ["grid.x.num=16", "grid.y.num=16"])
    path = tmp_path_factory.mktemp("partial") / "part.h5"
    small_sweep(cfg, path, shard=(0, 2), tile_shape=(8, 8))
    return path


def test_measure_file_matches_the_map_and_the_cli_writes_json_and_pictures(fig08_file, tmp_path):
    measures = measure_file(fig08_file)
    outcome = read_sweep(fig08_file).outcome
    assert measures.entropy.sb == basin_entropy(outcome).sb
    result = invoke("measure", fig08_file, "--json", tmp_path / "m.json", "--png", tmp_path / "png")
    assert result.exit_code == 0, result.output
    assert "uncertainty exponent alpha" in result.output
    numbers = json.loads((tmp_path / "m.json").read_text())
    assert numbers["basin_entropy"]["Sb"] == pytest.approx(measures.entropy.sb)
    assert numbers["uncertainty"]["alpha"] == pytest.approx(measures.uncertainty.fit.alpha)
    # f(eps): one panel at 100 dpi, the points and the fitted line in the first curve colour,
    # across the plot and rising with eps (the uncertain share grows with the perturbation)
    png = tmp_path / "png" / "uncertainty.png"
    assert png_size(png) == figure_pixels(plotting.PANEL_FIGSIZE, 100)
    rows, columns = np.nonzero(near(read_png(png), plotting.curve_colors(1)[0], tol=0.1))
    assert rows.size > 300
    assert np.ptp(columns) > 0.5 * png_size(png)[0]
    quarter = np.ptp(columns) / 4
    left, right = columns < columns.min() + quarter, columns > columns.max() - quarter
    assert np.median(rows[left]) > np.median(rows[right]) + 50  # rows count down the picture
    # box entropies: the map's black (magma at 0 nats) is the share of boxes off every boundary
    png = tmp_path / "png" / "box_entropy.png"
    assert png_size(png) == figure_pixels(plotting.PANEL_FIGSIZE, 100)
    region = map_region(read_png(png))
    assert share(region, MAGMA(0.0)) == pytest.approx(np.mean(measures.entropy.box_entropy == 0), abs=0.02)
    assert 0.3 < share(region, MAGMA(0.0)) < 0.9  # boxes on and off a boundary both drawn


def test_measure_refuses_an_incomplete_sweep(partial_file):
    path = partial_file
    result = invoke("measure", path)
    assert result.exit_code == 2
    assert result.output.count("\n") == 1 and "not computed" in result.output


def test_control_cli_writes_the_maps_and_rejects_bad_sigmas(fig08_file, tmp_path):
    result = invoke("control", fig08_file, "--sigma", "y0=0.006", "--sigma", "omega0=1.5",
                    "--png", tmp_path / "png", "--json", tmp_path / "c.json", "-o", tmp_path / "c.npz")
    assert result.exit_code == 0, result.output
    assert "Gaussian blur" in result.output
    assert json.loads((tmp_path / "c.json").read_text())["method"] == "blur"
    maps = np.load(tmp_path / "c.npz")
    assert maps["probability"].shape == (5, 128, 128)
    # three panels at 100 dpi: the most likely side in the side colours, its probability
    # (viridis, 0 to 1) and the entropy (magma, 0 to ln 4), each colour in the share of the
    # cells the maps give it
    png = tmp_path / "png" / "control.png"
    width, height = figure_pixels(plotting.PANEL_FIGSIZE, 100)
    assert png_size(png) == (3 * width, height)
    image = read_png(png)
    colours = {tuple(c): maps["most_likely"] == side for side, c in enumerate(plotting.outcome_colors(4))}
    colours[plotting.UNDECIDED_COLOR] = maps["most_likely"] == -1
    region = map_region(image[:, :width], colours)
    for colour, cells in colours.items():
        assert share(region, colour) == pytest.approx(cells.mean(), abs=0.02), colour
    # the cells sure of their side: probability 1 (viridis' yellow), entropy 0 (magma's black)
    for panel, cmap, scaled, sure in ((1, VIRIDIS, maps["p_max"], 1.0), (2, MAGMA, maps["entropy"] / math.log(4), 0.0)):
        region = map_region(image[:, panel * width : (panel + 1) * width])
        expected = near(cmap(scaled), cmap(sure)).mean()
        assert 0.05 < expected < 0.95
        assert share(region, cmap(sure)) == pytest.approx(expected, abs=0.02), panel
    for bad in (["--sigma", "y0=-1"], ["--sigma", "spin=1"], []):
        result = invoke("control", fig08_file, *bad)
        assert result.exit_code == 2 and result.output.count("\n") == 1, result.output


def test_an_incomplete_sweep_is_refused_with_the_count_of_cells_not_computed(partial_file, fig08_file):
    missing = int((~read_sweep(partial_file).computed).sum())
    assert 0 < missing < 256
    with pytest.raises(DiceSweepError, match=f"^{partial_file}: {missing} cells not computed; finish the sweep with --resume first$"):
        read_complete_sweep(partial_file)
    with pytest.raises(DiceSweepError, match="not computed"):
        run_control(partial_file, {"y0": 0.006})
    assert read_complete_sweep(fig08_file).computed.all()


def test_run_measure_writes_what_it_returns_and_nothing_unasked(fig08_file, tmp_path):
    measures = run_measure(fig08_file, box_size=4, json_path=tmp_path / "m.json")
    sweep = read_sweep(fig08_file)
    expected = measure_map(sweep.outcome, sweep.sides, 4, x_step=sweep.x.cell_width, y_step=sweep.y.cell_width)
    assert measures.to_dict() == expected.to_dict()
    assert json.loads((tmp_path / "m.json").read_text()) == {"file": str(fig08_file), **json.loads(json.dumps(expected.to_dict()))}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json"]  # no pictures unless asked


def test_outputs_are_checked_before_the_work(fig08_file, tmp_path):
    (tmp_path / "file").write_text("")
    with pytest.raises(DiceSweepError, match="--png"):
        run_measure(fig08_file, json_path=tmp_path / "m.json", png_dir=tmp_path / "file")  # a file, not a folder
    with pytest.raises(DiceSweepError, match="--json"):
        run_control(fig08_file, {"y0": 0.006}, json_path=tmp_path / "no" / "such" / "c.json")
    assert not (tmp_path / "m.json").exists()


def test_measure_of_a_probability_sweep_reports_the_predictable_share_and_basin_entropy(tmp_path):
    """fig08 at 16 x 16 with [scatter] draws 16: the command's numbers are those of the file's
    shares, in its text and its JSON."""
    cfg = load_config(CONFIGS / "fig08.toml", ["grid.x.num=16", "grid.y.num=16", "scatter.corner=0.1",
                                               "scatter.flat=0.1", "scatter.draws=16"])
    path = tmp_path / "p.h5"
    small_sweep(cfg, path)
    shares = read_sweep(path).probability
    result = invoke("measure", path, "--json", tmp_path / "p.json")
    assert result.exit_code == 0, result.output
    numbers = json.loads((tmp_path / "p.json").read_text())["probability"]
    predictable = float((shares[:-1].max(axis=0) >= 0.9).mean())
    assert numbers["predictable_share"] == predictable and numbers["draws"] == 16
    entropy = -np.sum(np.where(shares > 0, shares * np.log(np.where(shares > 0, shares, 1)), 0), axis=0)
    assert numbers["basin_entropy_nats"] == pytest.approx(entropy.mean(), rel=1e-6)
    assert 0 < numbers["basin_entropy_nats"] < math.log(5)
    assert f"predictable (one side p >= 0.9) {predictable:.4f}" in result.output
    assert "draw 0 of each pixel" in result.output
