"""The screenshot of docs/view.md: ``dice-sweep view`` on Fig. 11's map, zoomed into Fig. 12's
box (the page's zoom function: a drag lands on whole pixels), one pixel clicked and rolled, in headless Chromium (Debian's chromium, python playwright).

    python scripts/view_screenshot.py [--num 128] [--out docs/figures/view.png]

The sweep file goes to out/view/; the zoom is computed by the kernel at screen resolution.
"""

import argparse
import threading
from pathlib import Path

from playwright.sync_api import sync_playwright

from dice_sweep.config import load_config
from dice_sweep.sweep import run_sweep
from dice_sweep.view.app import ViewApp
from dice_sweep.view.headless import launch, open_page, wait_until
from dice_sweep.view.server import bind

ROOT = Path(__file__).resolve().parent.parent
ROLLED = (0.75, 0.0745)  # vx0 (m/s), y0 (m): a pixel of Fig. 12's box between fine bands


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num", type=int, default=128, help="cells per axis of the sweep file (default 128)")
    parser.add_argument("--out", default=str(ROOT / "docs" / "figures" / "view.png"))
    args = parser.parse_args()
    data = ROOT / "out" / "view" / f"fig11_{args.num}.h5"
    data.parent.mkdir(parents=True, exist_ok=True)
    data.unlink(missing_ok=True)
    run_sweep(load_config(ROOT / "configs" / "fig11.toml", [f"grid.x.num={args.num}", f"grid.y.num={args.num}"]),
              data, progress=False)
    box = load_config(ROOT / "configs" / "fig12.toml").grid

    app = ViewApp(data)
    server = bind(app, port=0)
    app.start()
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        with sync_playwright() as playwright:
            browser = launch(playwright)
            page, plot = open_page(browser, server, viewport=(1360, 980))
            grid = app.cfg.grid

            def screen(x, y):
                view = page.evaluate("window.diceView.state.view")
                return (plot["left"] + (x - view["xmin"]) / (view["xmax"] - view["xmin"]) * plot["width"],
                        plot["top"] + (view["ymax"] - y) / (view["ymax"] - view["ymin"]) * plot["height"])

            assert (grid.x.param, grid.y.param) == (box.x.param, box.y.param)
            # Fig. 12's box exactly: the zoom a drag calls (a drag itself lands on whole screen pixels)
            page.evaluate(f"window.diceView.zoomTo({box.x.min}, {box.x.max}, {box.y.min}, {box.y.max})")
            wait_until(page, "window.diceView.state.requests.length === 1 && window.diceView.state.status === 'idle'", 300)
            page.mouse.click(*screen(*ROLLED))
            wait_until(page, "window.diceView.state.roll !== null")
            page.screenshot(path=args.out)
            browser.close()
    finally:
        server.shutdown()
        server.server_close()
        app.close()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
