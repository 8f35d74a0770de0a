"""The ``view`` command: a sweep file's final-state diagram in the browser, zoomed by the
mapper (dice_sweep.view: its API, server and worker processes; docs/view.md)."""

from __future__ import annotations


def view(h5_path, *, host: str = "127.0.0.1", port: int | None = None, open_browser: bool = True,
         workers: int | None = None, echo=print, warn=None) -> None:
    """Serve the page of sweep file ``h5_path`` until Ctrl-C, then return
    (:func:`dice_sweep.view.server.serve`: the port, the host and the file are checked there,
    before the first line, ``serving on http://HOST:PORT/``, goes to ``echo``)."""
    from dice_sweep.view.server import serve  # the HTTP server: only for this command (start-up time)

    serve(h5_path, host=host, port=port, open_browser=open_browser, workers=workers, echo=echo, warn=warn)
