"""The local web server of ``dice-sweep view`` (docs/view.md): the standard library's
threading HTTP server, the page's assets from the package, and the JSON API of
:mod:`dice_sweep.view.app`.

Why the standard library: the API is four GET routes over one file, served to one user on
loopback; ``http.server`` does that with no dependency to install or keep up to date, and
its threads suit the page's few requests while the rolls run in worker processes. What a
framework would add (routing, templates, async) is not needed here.
"""

from __future__ import annotations

import errno
import ipaddress
import json
import os
import signal
import socket
import sys
import threading
import traceback
import webbrowser
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from urllib.parse import parse_qs, urlsplit

from dice_sweep import __version__
from dice_sweep.errors import DiceSweepError
from dice_sweep.view.app import Busy, QueryError, ViewApp
from dice_sweep.view.pool import Cancelled

DEFAULT_PORT = 8765  # when taken, and no --port was given, a free one is used instead
PORT_RANGE = (0, 65535)
REQUEST_TIMEOUT = 30.0  # s a connection may take to send its request: no idle thread lingers
CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
}
# the page loads nothing from elsewhere: no CDN, no font service (the machine may be offline)
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data: blob:; style-src 'self'; "
                               "script-src 'self'; connect-src 'self'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


def load_assets() -> dict[str, tuple[bytes, str]]:
    """URL path -> (bytes, content type) of every file in the package's static folder.

    Served from this table only: a path is looked up, never joined to a folder, so no
    request can reach another file.
    """
    assets = {}
    folder = resources.files("dice_sweep.view") / "static"
    for entry in folder.iterdir():
        suffix = os.path.splitext(entry.name)[1]
        if entry.is_file() and suffix in CONTENT_TYPES:
            assets[f"/static/{entry.name}"] = (entry.read_bytes(), CONTENT_TYPES[suffix])
    assets["/"] = assets["/static/index.html"]
    return assets


def _loopback(host: str) -> bool:
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _host_of(header: str) -> str:
    """Host name of a Host header, without its port (``[::1]:8765`` -> ``::1``)."""
    if header.startswith("["):
        return header[1:].split("]", 1)[0]
    return header.rsplit(":", 1)[0] if header.count(":") == 1 else header


class ViewServer(ThreadingHTTPServer):
    """One thread per request; the app and the assets shared."""

    daemon_threads = True

    def __init__(self, address, app: ViewApp, loopback_only: bool):
        host = address[0]
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.app = app
        self.assets = load_assets()
        self.loopback_only = loopback_only
        self.stopping = threading.Event()
        super().__init__(address, ViewHandler)

    def log_map(self, result: dict) -> None:
        """One line on stderr per map computed: what the terminal shows instead of an access log."""
        print(f"map {result['nx']} x {result['ny']} of {result['x_param']} [{result['xmin']:.6g}, {result['xmax']:.6g}], "
              f"{result['y_param']} [{result['ymin']:.6g}, {result['ymax']:.6g}]: {result['rolls']} rolls in "
              f"{result['seconds']:.2f} s", file=sys.stderr, flush=True)

    def handle_error(self, request, client_address):
        # a browser that closes a connection early is not an error worth a traceback
        error = sys.exc_info()[1]
        if self.stopping.is_set() or isinstance(error, (ConnectionError, TimeoutError, Cancelled)):
            return
        super().handle_error(request, client_address)


class ViewHandler(BaseHTTPRequestHandler):
    """GET routes: ``/``, ``/static/NAME``, ``/api/file``, ``/api/map``, ``/api/roll``, ``/api/config``."""

    server_version = f"dice-sweep-view/{__version__}"
    timeout = REQUEST_TIMEOUT

    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        pass  # no access log: the terminal shows what was computed instead

    # --- answers ----------------------------------------------------------------------------

    def _send(self, status: int, body: bytes, content_type: str, extra=None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for name, value in {**SECURITY_HEADERS, **(extra or {})}.items():
            self.send_header(name, value)
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status: int, data: dict) -> None:
        body = json.dumps(data, allow_nan=False, separators=(",", ":")).encode()
        self._send(status, body, "application/json", {"Cache-Control": "no-store"})

    def _error(self, status: int, message: str, parameter: str | None = None) -> None:
        data = {"error": message}
        if parameter is not None:
            data["parameter"] = parameter
        self._json(status, data)

    # --- routes -----------------------------------------------------------------------------

    def do_GET(self):  # noqa: N802 - http.server's name
        url = urlsplit(self.path)
        if self.server.loopback_only and not _loopback(_host_of(self.headers.get("Host", ""))):
            # a page elsewhere that points a name of its own at 127.0.0.1 (DNS rebinding) is refused
            return self._error(HTTPStatus.FORBIDDEN, "Host: only a loopback name (127.0.0.1, localhost, [::1]) is served")
        if url.path in self.server.assets and not url.query:
            body, content_type = self.server.assets[url.path]
            return self._send(HTTPStatus.OK, body, content_type, {"Cache-Control": "no-cache"})
        routes = {"/api/file": self._file, "/api/map": self._map, "/api/roll": self._roll, "/api/config": self._config}
        route = routes.get(url.path)
        if route is None:
            return self._error(HTTPStatus.NOT_FOUND, f"{url.path[:200]}: not found (this server has the page, "
                               "its /static/ files and /api/file, /api/map, /api/roll, /api/config)")
        query = parse_qs(url.query, keep_blank_values=True)
        try:
            route(query)
        except QueryError as error:
            self._json(HTTPStatus.BAD_REQUEST, error.to_dict())
        except Busy as error:
            self._error(HTTPStatus.SERVICE_UNAVAILABLE, str(error))
        except (Cancelled, ConnectionError, TimeoutError):
            pass  # the page went elsewhere, or the server is stopping
        except Exception as error:  # noqa: BLE001 - one answer per request, whatever failed
            if self.server.stopping.is_set():
                return
            traceback.print_exc()
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"{type(error).__name__}: {' '.join(str(error).split())}")

    def _not_allowed(self):
        self._error(HTTPStatus.METHOD_NOT_ALLOWED, f"{self.command}: not allowed (this server only answers GET)")

    do_HEAD = do_POST = do_PUT = do_DELETE = do_PATCH = do_OPTIONS = _not_allowed

    def _file(self, query):
        if query:
            raise QueryError(next(iter(query)), "unknown parameter (allowed: none)")
        self._json(HTTPStatus.OK, self.server.app.file_json())

    def _map(self, query):
        stream = query.pop("stream", ["0"])
        if stream not in (["0"], ["1"]):
            raise QueryError("stream", f"{stream[-1][:40]!r} is not allowed (allowed: 0 or 1, once)")
        app = self.server.app
        request = app.map_request(query)
        if stream == ["1"]:
            return self._map_stream(request)
        result = app.compute_map(request, cancelled=self.server.stopping.is_set)
        self.server.log_map(result)
        self._json(HTTPStatus.OK, result)

    def _map_stream(self, request):
        """The map as NDJSON lines: ``start``, a ``band`` per band of rows rolled, ``result``.

        A page that moves on closes the connection; the next line then fails to send and
        the rolls not started are dropped.
        """
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "application/x-ndjson")
        self.send_header("Cache-Control", "no-store")
        for name, value in SECURITY_HEADERS.items():
            self.send_header(name, value)
        self.end_headers()

        def line(data):
            self.wfile.write(json.dumps(data, allow_nan=False, separators=(",", ":")).encode() + b"\n")
            self.wfile.flush()

        total = request.nx * request.ny * self.server.app.draws
        line({"event": "start", "total": total, "nx": request.nx, "ny": request.ny})

        def band(first, end, rows, done, **shares):  # a probability map's band also has p_max and entropy rows
            line({"event": "band", "rows": [first, end], "outcome": rows.tolist(), **{name: values.tolist() for name, values in shares.items()},
                  "done": done, "total": total})

        result = self.server.app.compute_map(request, on_band=band, cancelled=self.server.stopping.is_set)
        self.server.log_map(result)
        line({"event": "result", **result})

    def _roll(self, query):
        self._json(HTTPStatus.OK, self.server.app.roll_json(query))

    def _config(self, query):
        request = self.server.app.map_request(query)
        body = self.server.app.config_text(request).encode()
        self._send(HTTPStatus.OK, body, "application/toml; charset=utf-8",
                   {"Cache-Control": "no-store", "Content-Disposition": 'attachment; filename="view.toml"'})


# --- serving --------------------------------------------------------------------------------


def check_port(port):
    """``port`` if it lies in PORT_RANGE (None: the default), else a one-line error."""
    low, high = PORT_RANGE
    if port is not None and not low <= port <= high:
        raise DiceSweepError(f"--port: {port} is outside the allowed range [{low}, {high}] (0 picks a free port)")
    return port


def url_of(server: ViewServer) -> str:
    host, port = server.server_address[:2]
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


def bind(app: ViewApp, host: str = "127.0.0.1", port: int | None = None) -> ViewServer:
    """A server for ``app`` listening on ``host``:``port`` (None: DEFAULT_PORT, or a free one
    if it is taken); a one-line error naming the option if it cannot listen there."""
    check_port(port)
    if not host or any(c.isspace() for c in host):
        raise DiceSweepError(f"--host: {host!r} is not an address (allowed: an IP address or a name, e.g. 127.0.0.1)")
    loopback_only = _loopback(host)
    tries = [DEFAULT_PORT, 0] if port is None else [port]
    for attempt in tries:
        try:
            return ViewServer((host.strip("[]"), attempt), app, loopback_only)
        except OSError as error:
            if error.errno == errno.EADDRINUSE and attempt != tries[-1]:
                continue
            if isinstance(error, socket.gaierror) or error.errno == errno.EADDRNOTAVAIL:
                raise DiceSweepError(f"--host: cannot listen on {host!r} ({error.strerror or error}; allowed: an "
                                     "address of this machine, e.g. 127.0.0.1)") from None
            advice = {errno.EADDRINUSE: "in use by another program; choose another, or 0 for a free one",
                      errno.EACCES: "permission denied (ports below 1024 need root); choose another, or 0 for a free one"}
            raise DiceSweepError(f"--port: cannot listen on {attempt} ({advice.get(error.errno, error.strerror or error)})") from None
    raise AssertionError("unreachable")


def _can_open_browser() -> bool:
    # without a display, webbrowser would start a text browser in this terminal
    if sys.platform in ("darwin", "win32") or os.environ.get("BROWSER"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _stop_on_sigterm():
    if threading.current_thread() is not threading.main_thread():
        return
    def stop(signum, frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, stop)


def serve(path, *, host: str = "127.0.0.1", port: int | None = None, open_browser: bool = True,
          workers: int | None = None, echo=print, warn=None) -> None:
    """Serve the page of sweep file ``path`` until Ctrl-C (or SIGTERM), then return.

    The first line written with ``echo`` is ``serving on http://HOST:PORT/``. Everything is
    checked before it (the file, the port, the host), each failure a one-line
    :class:`DiceSweepError` naming the option or the file.
    """
    check_port(port)
    app = ViewApp(path, workers)
    server = bind(app, host, port)
    try:
        _stop_on_sigterm()
        app.start()
        url = url_of(server)
        echo(f"serving on {url}")
        if warn is not None:
            if not server.loopback_only:
                warn(f"--host {host}: the map and the kernel are open to every machine that reaches this address")
            if not app.complete:
                warn(f"{path}: not complete; the cells not computed yet are grey until a zoom computes them")
        echo("press Ctrl-C to stop")
        if open_browser:
            local = url if server.loopback_only else f"http://127.0.0.1:{server.server_address[1]}/"
            if _can_open_browser():
                threading.Thread(target=webbrowser.open, args=(local,), daemon=True).start()
            elif warn is not None:
                warn("no display to open a browser on: open the address above in one (--no-open: no such attempt)")
        server.serve_forever(poll_interval=0.25)
    except KeyboardInterrupt:
        pass
    finally:
        server.stopping.set()
        server.server_close()
        app.close()
