"""The page of ``dice-sweep view`` in headless Chromium: what tests/view/ and
scripts/view_screenshot.py share. Takes a playwright browser (a test dependency, imported by
the caller); Debian's Chromium, never a browser download of playwright's own."""

import time

CHROMIUM = "/usr/bin/chromium"
BROWSER_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def launch(playwright):
    """Headless Chromium from /usr/bin/chromium."""
    return playwright.chromium.launch(executable_path=CHROMIUM, args=BROWSER_ARGS)


def wait_until(page, expression: str, timeout: float = 60.0) -> None:
    """Poll a JavaScript expression until it is true (playwright's wait_for_function needs
    eval, which the page's Content-Security-Policy forbids; page.evaluate does not)."""
    deadline = time.monotonic() + timeout
    while not page.evaluate(expression):
        if time.monotonic() > deadline:
            raise TimeoutError(f"timed out waiting for {expression}")
        time.sleep(0.05)


def open_page(browser, server, viewport=(1400, 1000), listen=None):
    """A page of ``server`` (a ViewServer), loaded and idle; returns (page, plot) with
    ``plot`` the map's plot area on the screen: left, top, width, height in CSS pixels.
    ``listen(page)`` is called before the page loads (to hear its console from the start)."""
    page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
    if listen is not None:
        listen(page)
    host, port = server.server_address[:2]
    page.goto(f"http://{host}:{port}/")
    wait_until(page, "window.diceView && window.diceView.state.status === 'idle'")
    plot = page.evaluate("window.diceView.plot")
    box = page.locator("#overlay").bounding_box()
    return page, {"left": box["x"] + plot["left"], "top": box["y"] + plot["top"], "width": plot["width"], "height": plot["height"]}
