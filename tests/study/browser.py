"""Open a local HTML file in Debian's headless chromium through Playwright, recording every
request, console message and page error (no browser is downloaded; nothing leaves the host:
any request that is not a file is recorded and aborted)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from playwright.sync_api import Page, Route, sync_playwright

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
WIDTH = 1200


@dataclass
class LoadedPage:
    """A page after its load event, and what happened while it loaded."""

    page: Page
    url: str
    requests: list[str] = field(default_factory=list)
    console: list[tuple[str, str]] = field(default_factory=list)  # (type, text)
    errors: list[str] = field(default_factory=list)


def _only_files(route: Route) -> None:
    if route.request.url.startswith("file:"):
        route.continue_()
    else:
        route.abort()


@contextmanager
def open_page(path: Path, *, width: int = WIDTH) -> Iterator[LoadedPage]:
    """Launch chromium (a fresh temporary profile), load ``path`` and yield it with its
    records; the browser is closed when the block ends."""
    url = path.resolve().as_uri()
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        try:
            context = browser.new_context(viewport={"width": width, "height": 900})
            context.route("**/*", _only_files)
            page = context.new_page()
            loaded = LoadedPage(page, url)
            context.on("request", lambda request: loaded.requests.append(request.url))
            page.on("console", lambda message: loaded.console.append((message.type, message.text)))
            page.on("pageerror", lambda error: loaded.errors.append(str(error)))
            page.goto(url, wait_until="load")
            yield loaded
        finally:
            browser.close()


def screenshot(html_path: Path, png_path: Path, *, width: int = WIDTH) -> Path:
    """A full-page PNG of ``html_path``, ``width`` pixels wide."""
    with open_page(html_path, width=width) as loaded:
        loaded.page.screenshot(path=str(png_path), full_page=True)
    return png_path
