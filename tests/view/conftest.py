"""The demo sweep file at 16 x 12 and a view server of it, in this process (port 0, a thread,
one worker process): one of each for all of tests/view/ (package scope)."""

import contextlib
import threading

import pytest

from dice_sweep.config import load_config
from dice_sweep.view.app import ViewApp
from dice_sweep.view.server import bind
from tests.helpers import small_sweep
from tests.view.client import DEMO, SMALL


@contextlib.contextmanager
def serving(path):
    """A view server of the sweep file ``path`` in this process (port 0, a thread), one worker process."""
    app = ViewApp(path, workers=1)
    httpd = bind(app, port=0)
    app.start()
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True)
    thread.start()
    try:
        yield httpd
    finally:
        httpd.shutdown()
        httpd.stopping.set()
        httpd.server_close()
        app.close()


@pytest.fixture(scope="package")
def sweep_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("view") / "demo.h5"
    small_sweep(load_config(DEMO, SMALL), path)
    return path


@pytest.fixture(scope="package")
def server(sweep_file):
    with serving(sweep_file) as httpd:
        yield httpd
