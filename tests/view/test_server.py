"""Tests of dice_sweep.view.server (issue 19, docs/view.md): streamed maps, what is served and to
whom, the command's start and Ctrl-C and its one-line errors, the port check and the assets."""

import http.client
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time
import urllib.parse
import urllib.request

import numpy as np
import pytest

from dice_sweep.errors import DiceSweepError
from dice_sweep.view.server import CONTENT_TYPES, PORT_RANGE, check_port, load_assets, url_of
from tests.helpers import ctrl_c_reaches_it, run_cli
from tests.view.client import ZOOM, get, get_json

BIN = pathlib.Path(sys.executable).parent


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


# --- called directly -------------------------------------------------------------------------------


@pytest.mark.parametrize("port", [None, 0, 8765, 65535])
def test_ports_in_range_are_returned(port):
    assert check_port(port) == port


@pytest.mark.parametrize("port", [-1, 65536])
def test_ports_out_of_range_are_a_one_line_error(port):
    with pytest.raises(DiceSweepError) as error:
        check_port(port)
    assert str(error.value) == f"--port: {port} is outside the allowed range [{PORT_RANGE[0]}, {PORT_RANGE[1]}] (0 picks a free port)"


def test_url_of_a_server_brackets_an_ipv6_host():
    class Bound:
        def __init__(self, *address):
            self.server_address = address

    assert url_of(Bound("127.0.0.1", 8765)) == "http://127.0.0.1:8765/"
    assert url_of(Bound("::1", 8765, 0, 0)) == "http://[::1]:8765/"


def test_assets_are_the_static_files_with_their_types():
    assets = load_assets()
    static = pathlib.Path(__file__).resolve().parents[2] / "dice_sweep" / "view" / "static"
    files = sorted(p.name for p in static.iterdir() if p.suffix in CONTENT_TYPES)
    assert "index.html" in files
    assert sorted(assets) == sorted(["/", *(f"/static/{name}" for name in files)])
    for path, (body, kind) in assets.items():
        name = "index.html" if path == "/" else path.removeprefix("/static/")
        assert body == (static / name).read_bytes(), path
        assert kind == CONTENT_TYPES[pathlib.Path(name).suffix], path
