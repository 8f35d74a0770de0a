"""Tests of dice_sweep.view.headless: its polling on a stand-in page, and the page of ``dice-sweep
view`` in a real headless Chromium through it - drawing, zooming and rolling (skipped, with the
reason, where Chromium or playwright is missing)."""

import io
import os
import urllib.parse

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.roll import roll_config
from dice_sweep.storage import read_sweep
from dice_sweep.view.headless import BROWSER_ARGS, CHROMIUM, launch, open_page, wait_until
from dice_sweep.config import load_config
from dice_sweep.plotting.maps import shaded_sides
from tests.helpers import small_sweep
from tests.view.client import DEMO, SCATTERED, SMALL, get_json
from tests.view.conftest import serving


class CountingPage:
    """A stand-in for a playwright page: evaluate() answers False ``falses`` times, then True."""

    def __init__(self, falses):
        self.falses, self.asked = falses, []

    def evaluate(self, expression):
        self.asked.append(expression)
        return len(self.asked) > self.falses


def test_wait_until_polls_until_the_expression_is_true():
    page = CountingPage(3)
    wait_until(page, "window.ready", timeout=10.0)
    assert page.asked == ["window.ready"] * 4


def test_wait_until_gives_up_after_its_timeout_naming_the_expression():
    with pytest.raises(TimeoutError, match="^timed out waiting for window.never$"):
        wait_until(CountingPage(10**9), "window.never", timeout=0.2)


def test_launch_starts_debians_chromium_headless():
    launched = {}

    class Chromium:
        def launch(self, **options):
            launched.update(options)
            return "browser"

    class Playwright:
        chromium = Chromium()

    assert launch(Playwright()) == "browser"
    assert launched == {"executable_path": CHROMIUM, "args": BROWSER_ARGS} and "--headless" in BROWSER_ARGS


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


def shaded_as_drawn(sides, outcome, p_max):
    """RGB (ny, nx, 3), 0-255, of a probability map given as the API answers it (the most
    likely outcome and its p, rows up): the PNG's picture (plotting.shaded_sides)."""
    outcome, p_max = np.asarray(outcome), np.asarray(p_max, dtype=float)
    probability = np.zeros((sides + 1, *outcome.shape))
    rows, cols = np.indices(outcome.shape)
    probability[np.where(outcome < 0, sides, outcome), rows, cols] = p_max
    return np.round(255 * shaded_sides(probability, sides)).astype(int)


@pytest.fixture(scope="module")
def probability_server(tmp_path_factory):
    path = tmp_path_factory.mktemp("view_probability") / "p.h5"
    small_sweep(load_config(DEMO, [*SMALL, *SCATTERED]), path)
    with serving(path) as httpd:
        yield httpd, read_sweep(path)


def test_page_of_a_probability_file_draws_and_zooms_shaded_by_p(browser, probability_server):
    """A probability file (8 draws a cell of the scattered law): the page draws each cell's most
    likely side faded by its p as the PNG does (plotting.shaded_sides), says so when hovered,
    and a zoom draws the kernel's shares of the zoom, one cell per screen pixel."""
    server, sweep = probability_server
    problems = []

    def listen(page):
        page.on("console", lambda message: message.type == "error" and problems.append(message.text))
        page.on("pageerror", lambda error: problems.append(str(error)))

    page, screen = open_page(browser, server, listen=listen)
    ny, nx = sweep.outcome.shape
    best = np.argmax(sweep.probability, axis=0)
    outcome, p_max = np.where(best == 4, -1, best), sweep.probability.max(axis=0)
    assert np.mean(p_max < 0.9) > 0.2  # draws disagree in many cells: the shading is a real check
    image = plot_pixels(page)
    height, width = image.shape[:2]
    centres = image[((ny - 0.5 - np.arange(ny)) * height / ny).astype(int)][:, ((np.arange(nx) + 0.5) * width / nx).astype(int)]
    expected = shaded_as_drawn(4, outcome, p_max)
    assert np.abs(centres - expected).max() <= 3  # rounding of p to float32 and of the colours
    assert np.abs(centres - shaded_as_drawn(4, outcome, np.ones_like(p_max))).max() > 60  # not drawn at p = 1

    page.mouse.move(screen["left"] + 0.5 * screen["width"], screen["top"] + 0.5 * screen["height"])
    assert "of 8 draws, entropy" in page.inner_text("#readout") and "most likely" in page.inner_text("#readout")
    assert "8 draws per cell" in page.inner_text("#entropy")

    left, top = screen["left"], screen["top"]
    page.mouse.move(left + 120, top + 100)
    page.mouse.down()
    page.mouse.move(left + 220, top + 180, steps=6)
    page.mouse.up()
    wait_until(page, "window.diceView.state.requests.length === 1 && window.diceView.state.status === 'idle'", timeout=180)
    asked = page.evaluate("window.diceView.state.requests[0]")
    status, answer = get_json(server, "/api/map", **asked)
    assert status == 200 and answer["draws"] == 8
    drawn = plot_pixels(page)[::-1]  # image rows run down, map rows up; one cell per screen pixel
    expected = shaded_as_drawn(4, answer["outcome"], answer["p_max"])
    assert drawn.shape == expected.shape
    assert np.mean(np.abs(drawn - expected).max(axis=-1) <= 3) > 0.99
    assert problems == []
    page.close()
