"""Tests of dice_sweep.app.view: the view command serves a sweep file, after its checks."""

import pytest

from dice_sweep.app.view import view
from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from tests.helpers import small_sweep


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    cfg = parse_config('[grid]\nx = { param = "omega0", min = 0.0, max = 40.0, num = 4 }\n'
                       'y = { param = "y0", min = 0.03, max = 0.15, num = 4 }\n', "test.toml")
    path = tmp_path_factory.mktemp("view") / "small.h5"
    small_sweep(cfg, path)
    return path


def test_serves_the_file_and_says_where_first(sweep_file):
    lines = []

    def echo(line):
        lines.append(line)
        raise KeyboardInterrupt  # as Ctrl-C: the server stops and its workers with it

    view(sweep_file, port=0, open_browser=False, workers=1, echo=echo)
    assert len(lines) == 1 and lines[0].startswith("serving on http://127.0.0.1:")


@pytest.mark.parametrize(
    ("path", "options", "message"),
    [
        ("missing.h5", {}, "missing.h5: no such file"),
        (None, {"port": 70000}, "--port: 70000 is outside the allowed range"),
    ],
)
def test_refuses_before_serving(sweep_file, tmp_path, monkeypatch, path, options, message):
    monkeypatch.chdir(tmp_path)
    lines = []
    with pytest.raises(DiceSweepError, match=message):
        view(path or sweep_file, open_browser=False, workers=1, echo=lines.append, **options)
    assert lines == []
