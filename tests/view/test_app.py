"""dice-sweep view (issue 19, docs/view.md): the HTTP API against the kernel, its checks of
bad requests, what it refuses to serve, the command's start and Ctrl-C, and the page in a
real headless Chromium (skipped, with the reason, where Chromium or playwright is missing)."""

import http.client
import io
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.parse
import urllib.request

import numpy as np
import pytest

from dice_sweep.config import load_config, parse_config
from dice_sweep.roll import roll_config
from dice_sweep.storage import read_sweep
from dice_sweep.mapper import Mapper, initial_states
from dice_sweep.sweep import axis_values
from dice_sweep.view.app import MAX_PIXELS, ViewApp
from dice_sweep.view.headless import CHROMIUM, launch, open_page, wait_until
from dice_sweep.view.server import bind
from tests.helpers import CONFIGS, ctrl_c_reaches_it, run_cli, small_sweep

DEMO = CONFIGS / "demo.toml"
SMALL = ["grid.x.num=16", "grid.y.num=12"]
ZOOM = {"xmin": 20.0, "xmax": 35.0, "ymin": 0.05, "ymax": 0.12, "nx": 10, "ny": 7}
BIN = pathlib.Path(sys.executable).parent


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("view") / "demo.h5"
    small_sweep(load_config(DEMO, SMALL), path)
    return path


@pytest.fixture(scope="module")
def server(sweep_file):
    """The server in this process (port 0, a thread), one worker process."""
    app = ViewApp(sweep_file, workers=1)
    httpd = bind(app, port=0)
    app.start()
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True)
    thread.start()
    yield httpd
    httpd.shutdown()
    httpd.stopping.set()
    httpd.server_close()
    app.close()


def get(server, target, headers=None):
    """(status, headers, body) of GET target, sent as written (no normalising of ..)."""
    connection = http.client.HTTPConnection(*server.server_address[:2], timeout=60)
    try:
        connection.request("GET", target, headers=headers or {})
        response = connection.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        connection.close()


def get_json(server, route, **params):
    status, _, body = get(server, f"{route}?{urllib.parse.urlencode(params)}" if params else route)
    return status, json.loads(body)


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


def zoom_config(zoom):
    overrides = [*SMALL, f"grid.x.min={zoom['xmin']}", f"grid.x.max={zoom['xmax']}", f"grid.x.num={zoom['nx']}",
                 f"grid.y.min={zoom['ymin']}", f"grid.y.max={zoom['ymax']}", f"grid.y.num={zoom['ny']}"]
    return load_config(DEMO, overrides)


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


def test_streamed_map_sends_every_band_then_the_same_map(server):
    status, headers, body = get(server, "/api/map?" + urllib.parse.urlencode({**ZOOM, "stream": 1}))
    assert status == 200 and headers["Content-Type"] == "application/x-ndjson"
    lines = [json.loads(line) for line in body.decode().splitlines()]
    assert lines[0] == {"event": "start", "total": ZOOM["nx"] * ZOOM["ny"], "nx": ZOOM["nx"], "ny": ZOOM["ny"]}
    bands = [line for line in lines if line["event"] == "band"]
    assert lines[-1]["event"] == "result" and bands[-1]["done"] == bands[-1]["total"]
    rows = np.full((ZOOM["ny"], ZOOM["nx"]), -99)
    for band in bands:
        rows[slice(*band["rows"])] = band["outcome"]
    assert rows.tolist() == lines[-1]["outcome"] == get_json(server, "/api/map", **ZOOM)[1]["outcome"]


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


# --- what is served, and to whom ----------------------------------------------------------------


@pytest.mark.parametrize("target", ["/../", "/static/../../etc/passwd", "/static/%2e%2e/%2e%2e/etc/passwd",
                                    "/static/..%2f..%2fpyproject.toml", "/etc/passwd", "/static/", "/static",
                                    "/api/", "/api/map/../../etc/passwd", "/dice_sweep/view/app.py"])
def test_paths_outside_the_assets_are_404(server, target):
    status, _, body = get(server, target)
    assert status == 404
    assert b"root:" not in body and b"[project]" not in body


def test_the_page_and_its_assets_are_served_from_the_package_with_nothing_from_elsewhere(server):
    status, headers, page = get(server, "/")
    assert status == 200 and headers["Content-Type"].startswith("text/html")
    assert "default-src 'self'" in headers["Content-Security-Policy"]
    linked = re.findall(rb'(?:src|href)="([^"]+)"', page)
    assert linked and all(link.startswith(b"/static/") for link in linked)
    for link in linked:
        status, _, body = get(server, link.decode())
        assert status == 200 and body
        body = body.replace(b'xmlns="http://www.w3.org/2000/svg"', b"")  # a name, not a fetch
        assert not re.search(rb"https?://", body), link  # no CDN, no web font


def test_only_loopback_host_names_are_answered(server):
    assert get(server, "/api/file", {"Host": "evil.example:8765"})[0] == 403  # DNS rebinding
    assert get(server, "/api/file", {"Host": f"localhost:{server.server_address[1]}"})[0] == 200


def test_only_get(server):
    connection = http.client.HTTPConnection(*server.server_address[:2], timeout=10)
    connection.request("POST", "/api/map", body=b"x" * 100)
    assert connection.getresponse().status == 405
    connection.close()


# --- the command -----------------------------------------------------------------------------------


def start_view(*args):
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}"}
    process = subprocess.Popen(["dice-sweep", "view", *map(str, args)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=env, preexec_fn=ctrl_c_reaches_it)
    first = process.stdout.readline()
    return process, first


def test_command_serves_on_loopback_and_stops_cleanly_on_ctrl_c(sweep_file):
    process, first = start_view(sweep_file, "--port", "0", "--no-open", "--workers", "2")
    try:
        match = re.fullmatch(r"serving on http://127\.0\.0\.1:(\d+)/\n", first)
        assert match, first
        url = f"http://127.0.0.1:{match[1]}"
        with urllib.request.urlopen(f"{url}/api/map?" + urllib.parse.urlencode(ZOOM), timeout=120) as response:
            assert len(json.load(response)["outcome"]) == ZOOM["ny"]
        # a map being rolled when Ctrl-C comes
        connection = http.client.HTTPConnection("127.0.0.1", int(match[1]), timeout=60)
        connection.request("GET", "/api/map?" + urllib.parse.urlencode({**ZOOM, "nx": 512, "ny": 512, "stream": 1}))
        time.sleep(0.2)
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert process.returncode in (0, 130), err
    assert "Traceback" not in err + out, err


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["missing.h5"], "missing.h5: no such file"),
        (["{notsweep}"], "not an HDF5 file"),
        (["{sweep}", "--port", "70000"], "--port: 70000 is outside the allowed range [0, 65535]"),
        (["{sweep}", "--port", "-1"], "--port: -1 is outside the allowed range"),
        (["{sweep}", "--workers", "0"], "--workers: 0 is outside the allowed range"),
        (["{sweep}", "--host", "999.1.1.1"], "--host"),
    ],
)
def test_command_errors_are_one_line_exit_2(args, fragment, sweep_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notsweep.h5").write_text("not a sweep")
    args = [a.format(sweep=sweep_file, notsweep=tmp_path / "notsweep.h5") for a in args]
    result = run_cli("view", *args, "--no-open")
    assert result.exit_code == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0], result.stderr
    assert result.stdout == ""  # nothing served


def test_port_in_use_is_one_line_exit_2(sweep_file, server):
    result = run_cli("view", sweep_file, "--port", server.server_address[1], "--no-open")
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr.strip() == f"error: --port: cannot listen on {server.server_address[1]} (in use by another program; choose another, or 0 for a free one)"


# --- the page in a real browser --------------------------------------------------------------------

@pytest.fixture(scope="module")
def browser():
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"no {CHROMIUM}: apt-get install chromium (.ci/run does, as root)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("no playwright: pip install -e '.[test]'")
    with sync_playwright() as playwright:
        browser = launch(playwright)
        yield browser
        browser.close()


def plot_pixels(page):
    """RGB array of the plot area of the figure, from a screenshot (device pixel ratio 1)."""
    from PIL import Image

    plot = page.evaluate("window.diceView.plot")
    image = np.asarray(Image.open(io.BytesIO(page.locator("#map").screenshot())).convert("RGB"))
    return image[plot["top"] : plot["top"] + plot["height"], plot["left"] : plot["left"] + plot["width"]].astype(int)


def nearest_side(pixels, colours):
    """Index of the nearest colour of ``colours`` for every pixel, and its distance."""
    distance = np.stack([np.abs(pixels - np.array(c)).sum(axis=-1) for c in colours], axis=-1)
    return distance.argmin(axis=-1), distance.min(axis=-1)


def hex_rgb(text):
    return [int(text[k : k + 2], 16) for k in (1, 3, 5)]


def test_page_draws_zooms_and_rolls(browser, server, sweep_file):
    sweep = read_sweep(sweep_file)
    problems, maps_asked = [], []

    def listen(page):
        page.on("console", lambda message: message.type == "error" and problems.append(message.text))
        page.on("pageerror", lambda error: problems.append(str(error)))
        page.on("request", lambda request: "/api/map" in request.url and maps_asked.append(request.url))

    page, screen = open_page(browser, server, listen=listen)
    left, top = screen["left"], screen["top"]

    # the file's own map, in the paper's colours, in the file's proportions
    colours = [hex_rgb(c) for c in page.evaluate("window.diceView.state.file.colors.sides")]
    before = plot_pixels(page)
    side, distance = nearest_side(before, colours)
    assert np.mean(distance == 0) > 0.99  # nothing but side colours: no smoothing, no gaps
    for k in range(4):
        assert np.mean(side == k) == pytest.approx(np.mean(sweep.outcome == k), abs=0.02)

    # zoom: drag a box over part of the plot
    page.mouse.move(left + 256, top + 150)
    page.mouse.down()
    page.mouse.move(left + 400, top + 300, steps=6)
    page.mouse.up()
    wait_until(page, "window.diceView.state.requests.length === 1 && window.diceView.state.status === 'idle'")
    asked = page.evaluate("window.diceView.state.requests[0]")
    expected = {"xmin": 60 * 256 / 512, "xmax": 60 * 400 / 512, "ymin": 0.02 + 0.28 * (400 - 300) / 400, "ymax": 0.02 + 0.28 * (400 - 150) / 400}
    for key, value in expected.items():
        assert asked[key] == pytest.approx(value, rel=0.01), key
    assert (asked["nx"], asked["ny"]) == (screen["width"], screen["height"])  # screen resolution
    assert maps_asked and all("stream=1" in url for url in maps_asked)
    query = urllib.parse.parse_qs(urllib.parse.urlsplit(maps_asked[-1]).query)
    assert float(query["xmin"][0]) == asked["xmin"]
    after = plot_pixels(page)
    assert np.mean(np.any(after != before, axis=-1)) > 0.2
    # what is drawn is what the kernel answered, cell for cell (one cell per screen pixel)
    status, answer = get_json(server, "/api/map", **asked)
    drawn, distance = nearest_side(after[::-1], colours)  # image rows run down, map rows up
    assert status == 200 and np.mean(distance == 0) > 0.99
    assert np.mean(drawn == np.array(answer["outcome"])) > 0.99
    config_url = page.evaluate("window.diceView.configUrl()")
    assert urllib.parse.parse_qs(urllib.parse.urlsplit(config_url).query)["xmin"] == [str(asked["xmin"])]

    # scroll: zooms in around the cursor, recomputed once the wheel rests
    page.mouse.move(left + 100, top + 100)
    page.mouse.wheel(0, -400)
    wait_until(page, "window.diceView.state.requests.length === 2 && window.diceView.state.status === 'idle'")
    wheel = page.evaluate("window.diceView.state.requests[1]")
    assert wheel["xmax"] - wheel["xmin"] < 0.75 * (asked["xmax"] - asked["xmin"])
    assert wheel["xmin"] > asked["xmin"] and wheel["ymax"] < asked["ymax"]

    # click a pixel: its roll, drawn with side 0 in its colour
    page.mouse.click(left + 300, top + 200)
    wait_until(page, "window.diceView.state.roll !== null")
    cell = page.evaluate("window.diceView.cellAt(window.diceView.state.marker.x, window.diceView.state.marker.y)")
    rolled = page.evaluate("window.diceView.state.roll")
    cfg = parse_config(sweep.config_toml)
    report = roll_config(cfg.with_initial(omega0=rolled["x"], y0=rolled["y"]))
    assert rolled["outcome"] == report.outcome == cell["code"]
    assert page.inner_text("#roll-text").startswith(f"side {report.outcome} after {report.counts['impacts']} impacts")
    assert page.locator("#impacts tbody tr").count() == report.counts["impacts"]
    from PIL import Image

    die = np.asarray(Image.open(io.BytesIO(page.locator("#die").screenshot())).convert("RGB")).astype(int)
    assert rolled["colors"]["sides"][0] == "#ff0000"
    assert np.sum((die[..., 0] > 200) & (die[..., 1] < 90) & (die[..., 2] < 90)) > 20  # side 0, in red
    assert np.sum(np.all(np.abs(die - 217) <= 2, axis=-1)) > 1000  # the table
    page.click("#play")  # the animation runs to its end and leaves the Fig. 5 picture
    wait_until(page, "document.getElementById('play').textContent === 'Stop'")
    wait_until(page, "document.getElementById('play').textContent === 'Play'", timeout=4 * rolled["t_end"] / 0.25 + 10)
    assert problems == []
    page.close()


def test_page_of_a_sampled_file_rolls_the_cell_it_shows(browser, server, sweep_file, monkeypatch):
    import dice_sweep.view.app

    monkeypatch.setattr(dice_sweep.view.app, "MAX_FILE_PIXELS", 7)
    sweep = read_sweep(sweep_file)
    page, screen = open_page(browser, server)
    for fx, fy in [(0.1, 0.1), (0.5, 0.45), (0.93, 0.8)]:
        page.evaluate("window.diceView.state.roll = null")
        page.mouse.click(screen["left"] + fx * screen["width"], screen["top"] + fy * screen["height"])
        wait_until(page, "window.diceView.state.roll !== null")
        cell = page.evaluate("window.diceView.cellAt(window.diceView.state.marker.x, window.diceView.state.marker.y)")
        rolled = page.evaluate("window.diceView.state.roll")
        assert (rolled["x"], rolled["y"]) == (sweep.x.values[cell["i"]], sweep.y.values[cell["j"]])
        assert rolled["outcome"] == cell["code"] == sweep.outcome[cell["j"], cell["i"]]
    assert "16 x 12 cells" in page.inner_text("#stats-source")
    page.close()
