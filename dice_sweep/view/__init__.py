"""``dice-sweep view``: a sweep file's final-state diagram in the browser, zoomed by the
kernel, with single rolls drawn as in Smith 2014's Fig. 5 (docs/view.md).

:mod:`dice_sweep.view.app` answers the API (no HTTP), :mod:`dice_sweep.view.server` serves
it and the page's assets (``static/``), :mod:`dice_sweep.view.pool` rolls in worker processes.
"""
