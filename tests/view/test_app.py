"""Tests of dice_sweep.view.app (issue 19, docs/view.md): the API of ``dice-sweep view`` against
the kernel - the file's map, zooms, a pixel's roll, the exported config - and its checks of bad
requests, through a server of tests/view/conftest.py; the statistics and checks called directly.
The server's own work: tests/view/test_server.py; the page in a browser: test_headless.py."""

import json
import urllib.parse

import numpy as np
import pytest

from dice_sweep.chaos import basin_entropy
from dice_sweep.config import load_config, parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.chaos.measures import shannon_entropy
from dice_sweep.mapper import Mapper, initial_states, start_pixels
from dice_sweep.roll import roll_config
from dice_sweep.storage import read_sweep
from dice_sweep.sweep import axis_values
from dice_sweep.view.app import MAX_PIXELS, QueryError, ViewApp, draw_shares, map_stats
from tests.helpers import small_sweep
from tests.view.client import DEMO, SCATTERED, SMALL, ZOOM, get, get_json, zoom_config


# --- the API against the kernel ---------------------------------------------------------------


def test_map_of_the_files_own_range_and_size_is_the_files_outcome(server, sweep_file):
    sweep = read_sweep(sweep_file)
    status, info = get_json(server, "/api/file")
    assert status == 200
    x, y = info["x"], info["y"]
    status, answer = get_json(server, "/api/map", xmin=x["min"], xmax=x["max"], ymin=y["min"], ymax=y["max"],
                              nx=x["num"], ny=y["num"])
    assert status == 200
    assert np.array_equal(np.array(answer["outcome"], dtype=np.int8), sweep.outcome)
    assert answer["x"] == sweep.x.values.tolist() and answer["y"] == sweep.y.values.tolist()
    assert np.array_equal(np.array(info["outcome"]), sweep.outcome)  # /api/file: the file's own pixels
    shares = info["stats"]["shares"]["sides"]
    assert shares == pytest.approx([np.mean(sweep.outcome == side) for side in range(4)])


def test_a_large_file_is_sent_sampled_with_the_index_of_each_cell(server, sweep_file, monkeypatch):
    import dice_sweep.view.app

    monkeypatch.setattr(dice_sweep.view.app, "MAX_FILE_PIXELS", 5)
    sweep = read_sweep(sweep_file)
    status, info = get_json(server, "/api/file")
    rows, cols = info["y"]["index"], info["x"]["index"]
    assert status == 200 and (len(rows), len(cols)) == (5, 5)
    assert cols == [1, 4, 8, 11, 14] and rows == [1, 3, 6, 8, 10]  # the cell under each part's centre
    assert np.array_equal(np.array(info["outcome"]), sweep.outcome[np.ix_(rows, cols)])
    assert info["stats"]["shares"]["sides"] == pytest.approx([np.mean(sweep.outcome == k) for k in range(4)])


def test_zoomed_map_has_the_cell_centres_and_the_kernels_outcomes(server):
    status, answer = get_json(server, "/api/map", **ZOOM)
    assert status == 200
    centres_x = ZOOM["xmin"] + (np.arange(ZOOM["nx"]) + 0.5) * (ZOOM["xmax"] - ZOOM["xmin"]) / ZOOM["nx"]
    centres_y = ZOOM["ymin"] + (np.arange(ZOOM["ny"]) + 0.5) * (ZOOM["ymax"] - ZOOM["ymin"]) / ZOOM["ny"]
    assert np.allclose(answer["x"], centres_x, rtol=0, atol=1e-12) and np.allclose(answer["y"], centres_y, rtol=0, atol=1e-15)
    cfg = zoom_config(ZOOM)
    states = initial_states(cfg, axis_values(cfg.grid.x), axis_values(cfg.grid.y))
    expected = Mapper.from_config(cfg).roll(states).outcome.reshape(ZOOM["ny"], ZOOM["nx"])
    assert np.array_equal(np.array(answer["outcome"], dtype=np.int8), expected)
    assert len(set(np.unique(expected))) > 1  # the zoom crosses a boundary: a real check
    assert answer["stats"]["shares"]["sides"] == pytest.approx([np.mean(expected == side) for side in range(4)])


def test_roll_is_roll_config_from_that_start(server, sweep_file):
    sweep = read_sweep(sweep_file)
    cfg = parse_config(sweep.config_toml)
    for i, j in [(3, 2), (11, 8), (15, 11)]:
        x, y = float(sweep.x.values[i]), float(sweep.y.values[j])
        status, answer = get_json(server, "/api/roll", x=repr(x), y=repr(y))
        assert status == 200
        report = roll_config(cfg.with_initial(omega0=x, y0=y))
        assert answer["outcome"] == report.outcome == sweep.outcome[j, i]  # the pixel's own roll
        assert answer["t_decided"] == report.t_decided and answer["counts"] == report.counts
        assert len(answer["impacts"]) == report.counts["impacts"]
        times = answer["path"]["t"]
        assert times[0] == 0 and times[-1] == report.t_end and len(answer["path"]["phi"]) == len(times)
        assert (answer["path"]["x"][0], answer["path"]["y"][0]) == pytest.approx((0.0, y))
        assert all(impact["surface"] == "table" for impact in answer["impacts"])


def test_exported_toml_reproduces_the_view(server, tmp_path):
    small = {**ZOOM, "nx": 6, "ny": 5}
    status, headers, body = get(server, "/api/config?" + urllib.parse.urlencode(small))
    assert status == 200 and "attachment" in headers["Content-Disposition"]
    path = tmp_path / "view.toml"
    path.write_bytes(body)
    cfg = load_config(path)
    for name in ("x", "y"):
        axis = getattr(cfg.grid, name)
        assert (axis.min, axis.max, axis.num) == (small[f"{name}min"], small[f"{name}max"], small[f"n{name}"])
    small_sweep(cfg, tmp_path / "view.h5")
    assert read_sweep(tmp_path / "view.h5").outcome.tolist() == get_json(server, "/api/map", **small)[1]["outcome"]


# --- bad requests: 400 naming the parameter ------------------------------------------------------


@pytest.mark.parametrize(
    ("route", "change", "parameter", "fragment"),
    [
        ("/api/map", {"nx": 600}, "nx", f"[1, {MAX_PIXELS}]"),
        ("/api/map", {"ny": 0}, "ny", f"[1, {MAX_PIXELS}]"),
        ("/api/map", {"nx": "1.5"}, "nx", "whole number"),
        ("/api/map", {"xmin": "nan"}, "xmin", "finite"),
        ("/api/map", {"xmax": "1e999"}, "xmax", "finite"),
        ("/api/map", {"xmin": 40.0}, "xmax", "xmax > xmin"),
        ("/api/map", {"xmin": -1000.0}, "xmin", "allowed range"),
        ("/api/map", {"ymax": 5.0}, "ymax", "allowed range"),
        ("/api/map", {"ymin": 0.001}, "ymin", "into the table"),
        ("/api/map", {"ymax": None}, "ymax", "missing"),
        ("/api/map", {"colour": "red"}, "colour", "unknown parameter"),
        ("/api/map", {"stream": "yes"}, "stream", "0 or 1"),
        ("/api/config", {"nx": 100000}, "nx", f"[1, {MAX_PIXELS}]"),
        ("/api/roll", {"x": "abc"}, "x", "finite"),
        ("/api/roll", {"y": 0.002}, "y", "into the table"),
        ("/api/roll", {"x": 1e6}, "x", "allowed range"),
    ],
)
def test_bad_query_is_400_naming_the_parameter(server, route, change, parameter, fragment):
    params = dict(ZOOM) if route != "/api/roll" else {"x": 25.0, "y": 0.1}
    params.update(change)
    params = {key: value for key, value in params.items() if value is not None}
    status, answer = get_json(server, route, **params)
    assert status == 400
    assert answer["parameter"] == parameter
    assert answer["error"].startswith(f"{parameter}: ") and fragment in answer["error"]


def test_a_parameter_given_twice_is_refused(server):
    status, _, body = get(server, "/api/map?" + urllib.parse.urlencode(ZOOM) + "&nx=3")
    assert status == 400 and json.loads(body)["parameter"] == "nx"


# --- called directly -------------------------------------------------------------------------------


def test_map_stats_are_the_shares_by_hand_and_the_entropy_of_a_whole_map():
    outcome = np.zeros((10, 10), np.int8)
    outcome[:, 6:] = 2
    outcome[0, :3] = -1
    stats = map_stats(outcome, 4)
    assert stats["cells"] == 100
    assert stats["shares"] == {"undecided": 0.03, "sides": [0.57, 0.0, 0.4, 0.0]}
    entropy = basin_entropy(outcome, 5)
    assert stats["basin_entropy"]["Sb"] == entropy.sb and stats["basin_entropy"]["boundary_boxes"] == entropy.boundary_boxes
    computed = np.zeros_like(outcome, bool)
    computed[:, 5:] = True  # the right half: one column of side 0, four of side 2
    part = map_stats(outcome, 4, computed)
    assert part["cells"] == 50 and part["shares"]["sides"] == [0.2, 0.0, 0.8, 0.0]
    assert part["basin_entropy"] is None  # no entropy of a map with holes
    assert map_stats(outcome[:4, :4], 4)["basin_entropy"] is None  # smaller than one box


def test_a_map_request_is_checked_and_rolls_the_sweeps_starts(sweep_file):
    app = ViewApp(sweep_file, workers=1)  # not started: no worker process
    query = {key: [str(value)] for key, value in ZOOM.items()}
    request = app.map_request(query)
    assert (request.xmin, request.xmax, request.nx, request.ny) == (20.0, 35.0, 10, 7)
    assert request.cfg.grid == zoom_config(ZOOM).grid
    with pytest.raises(QueryError) as error:
        app.map_request({**query, "ny": ["0"]})
    assert error.value.parameter == "ny" and error.value.to_dict() == {"error": str(error.value), "parameter": "ny"}
    low, high = app.limits("x")
    width = app.cfg.grid.x.max - app.cfg.grid.x.min
    assert (low, high) == (app.cfg.grid.x.min - width, app.cfg.grid.x.max + width)
    with pytest.raises(RuntimeError, match="start"):
        app.compute_map(request)


def test_a_missing_file_or_a_file_of_another_kind_is_refused(tmp_path):
    with pytest.raises(DiceSweepError, match=f"^{tmp_path / 'missing.h5'}: no such file"):
        ViewApp(tmp_path / "missing.h5", workers=1)
    (tmp_path / "text.h5").write_text("not a sweep")
    with pytest.raises(DiceSweepError, match="not an HDF5 file"):
        ViewApp(tmp_path / "text.h5", workers=1)


# --- a probability file (draws > 1 of the scattered law) -------------------------------------

@pytest.fixture(scope="module")
def probability_app(tmp_path_factory):
    """The demo at 16 x 12 cells as a probability sweep (8 draws a cell), opened for viewing
    with one worker process; and the file as read back."""
    path = tmp_path_factory.mktemp("probability") / "p.h5"
    small_sweep(load_config(DEMO, [*SMALL, *SCATTERED]), path)
    app = ViewApp(path, workers=1)
    app.start()
    yield app, read_sweep(path)
    app.close()


def _request(app, **zoom):
    return app.map_request({name: [repr(value)] for name, value in zoom.items()})


def test_a_probability_zoom_of_the_files_grid_rolls_each_pixels_own_draws(probability_app):
    """The file's own range and size: every zoom cell is a file cell, rolled on its streams, so
    its shares are the file's bit for bit, and the page gets the file's shaded map."""
    app, sweep = probability_app
    x, y = app.cfg.grid.x, app.cfg.grid.y
    request = _request(app, xmin=x.min, xmax=x.max, ymin=y.min, ymax=y.max, nx=x.num, ny=y.num)
    outcome, _ = app.roll_zoom(request)
    assert outcome.shape == (y.num, x.num, 8)
    assert np.array_equal(draw_shares(outcome, 4), sweep.probability)
    assert np.mean(sweep.probability.max(axis=0) < 1) > 0.2  # the law scatters: draws differ, a real check
    answer, info = app.compute_map(request), app.file_json()
    for name in ("outcome", "p_max", "entropy"):
        assert answer[name] == info[name], name
    best = np.argmax(sweep.probability, axis=0)
    assert np.array_equal(answer["outcome"], np.where(best == 4, -1, best))
    assert np.allclose(answer["p_max"], sweep.probability.max(axis=0), rtol=0, atol=1e-6)
    assert np.allclose(answer["entropy"], shannon_entropy(sweep.probability), rtol=0, atol=1e-6)
    assert answer["draws"] == info["draws"] == 8 and answer["rolls"] == x.num * y.num * 8
    assert answer["stats"]["probability"]["draws"] == 8


def test_a_zoom_cell_on_a_file_cells_centre_has_its_shares_and_other_starts_streams_of_their_own(probability_app):
    """Three cells per file column over four columns: the middle one of each three is on a
    file cell's centre (bit for bit) and has its shares; the others roll streams no file pixel
    has, the same in a wider zoom that holds the same starts."""
    app, sweep = probability_app
    x, y = app.cfg.grid.x, app.cfg.grid.y
    width = (x.max - x.min) / x.num
    zoom = {"xmin": x.min + 2 * width, "xmax": x.min + 6 * width, "ymin": y.min, "ymax": y.max, "nx": 12, "ny": y.num}
    request = _request(app, **zoom)
    shares = draw_shares(app.roll_zoom(request)[0], 4)
    xs = request.cfg.grid.x.values()
    on_file = np.flatnonzero(np.isin(xs, sweep.x.values))
    assert on_file.tolist() == [1, 4, 7, 10]  # the middle of each three
    assert np.array_equal(shares[:, :, on_file], sweep.probability[:, :, 2:6])
    pixels = start_pixels(sweep.x.values, sweep.y.values, np.tile(xs, y.num), np.repeat(request.cfg.grid.y.values(), 12))
    off = ~np.isin(np.tile(np.arange(12), y.num), on_file)
    assert np.all((pixels[off] >= 2**52) & (pixels[off] < 2**53))
    wider = _request(app, **{**zoom, "xmax": x.min + 10 * width, "nx": 24})  # the same 12 starts, and 12 more
    assert np.array_equal(wider.cfg.grid.x.values()[:12], xs)
    assert np.array_equal(draw_shares(app.roll_zoom(wider)[0], 4)[:, :, :12], shares)


def test_a_deterministic_files_zoom_is_one_roll_per_start(server):
    """The file of one roll per start: no draws, no shares in the answer."""
    status, answer = get_json(server, "/api/map", **ZOOM)
    assert status == 200 and answer["draws"] == 1 and "p_max" not in answer and answer["stats"]["probability"] is None
