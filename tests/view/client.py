"""What the tests of dice_sweep.view share: the demo file's grid, a zoom of it, and GET
requests to a running server sent as written (tests/view/conftest.py starts the server)."""

import http.client
import json
import urllib.parse

from dice_sweep.config import load_config
from tests.helpers import CONFIGS

DEMO = CONFIGS / "demo.toml"
SMALL = ["grid.x.num=16", "grid.y.num=12"]
# the scattered law at 8 draws a cell: a probability file of the demo
SCATTERED = ["scatter.corner=0.1", "scatter.flat=0.1", "scatter.corner_floor=0.05", "scatter.draws=8", "scatter.seed=5"]
ZOOM = {"xmin": 20.0, "xmax": 35.0, "ymin": 0.05, "ymax": 0.12, "nx": 10, "ny": 7}


def get(server, target, headers=None):
    """(status, headers, body) of GET target, sent as written (no normalising of ..)."""
    # a zoom may compile or roll for minutes on a loaded machine: the timeout only stops a hang
    connection = http.client.HTTPConnection(*server.server_address[:2], timeout=600)
    try:
        connection.request("GET", target, headers=headers or {})
        response = connection.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        connection.close()


def get_json(server, route, **params):
    status, _, body = get(server, f"{route}?{urllib.parse.urlencode(params)}" if params else route)
    return status, json.loads(body)


def zoom_config(zoom):
    """The demo config at the grid of a zoom (its range and cells)."""
    overrides = [*SMALL, f"grid.x.min={zoom['xmin']}", f"grid.x.max={zoom['xmax']}", f"grid.x.num={zoom['nx']}",
                 f"grid.y.min={zoom['ymin']}", f"grid.y.max={zoom['ymax']}", f"grid.y.num={zoom['ny']}"]
    return load_config(DEMO, overrides)
