"""Screenshots of the viewer in a real headless Chromium (the browser test, README pictures).

Drives Debian's ``chromium`` (``/usr/bin/chromium``, installed by ``make``) through Playwright
(a ``dev`` dependency; no browser is downloaded). viser draws with WebGL; without a GPU,
Chromium renders it with SwiftShader, which it only allows with ``--enable-unsafe-swiftshader``.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["CHROMIUM_ARGS", "PageShot", "chromium_path", "save_png", "screenshot"]

CHROMIUM_ARGS = ("--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--ignore-gpu-blocklist")


def chromium_path() -> str | None:
    """Path of the system Chromium, or None when it is not installed."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


@dataclass
class PageShot:
    """A screenshot and what the page said while loading."""

    image: NDArray[np.uint8]  # (H, W, 3) RGB
    png: bytes
    console_errors: list[str] = field(default_factory=list)
    seconds_to_stable: float = float("nan")  # navigation (or action) → two equal, drawn frames


def _rgb(png: bytes) -> NDArray[np.uint8]:
    from PIL import Image

    return np.asarray(Image.open(BytesIO(png)).convert("RGB"))


def screenshot(url: str, width: int = 1280, height: int = 800, timeout_s: float = 90.0,
               settle_s: float = 1.0, actions: list[tuple[str, str]] | None = None
               ) -> list[PageShot]:
    """Load ``url`` in headless Chromium, wait until the 3-D view has drawn something and
    stopped changing, close the notifications (viser's "software WebGL" note), and take a
    screenshot; then one more after each action.

    ``actions``: ``("click_label", label)`` clicks the control with that label,
    ``("click_css", selector)`` the first element matching a CSS selector.
    Console errors and uncaught exceptions are collected on every shot (cumulative).
    """
    from playwright.sync_api import sync_playwright

    exe = chromium_path()
    if exe is None:
        raise RuntimeError("chromium is not installed (Debian: apt-get install chromium; "
                           "`make` does it)")
    errors: list[str] = []
    shots: list[PageShot] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=list(CHROMIUM_ARGS))
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            page.set_default_timeout(timeout_s * 1000.0)  # every call, not playwright's 30 s
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"uncaught: {e}"))
            t0 = time.monotonic()
            page.goto(url)
            t_stable = _wait_stable(page, t0, timeout_s)
            for b in page.query_selector_all(".mantine-Notification-closeButton"):
                b.click()
            for kind, arg in [("", ""), *(actions or [])]:
                if kind == "click_label":
                    page.get_by_label(arg, exact=True).click()
                elif kind == "click_css":
                    page.locator(arg).first.click()
                elif kind:
                    raise ValueError(f"unknown action {kind!r}")
                time.sleep(settle_s)
                t = _wait_stable(page, time.monotonic(), timeout_s)
                png = page.screenshot()
                shots.append(PageShot(_rgb(png), png, list(errors),
                                      t_stable if not kind else t))
        finally:
            browser.close()
    return shots


def _wait_stable(page: object, t0: float, timeout_s: float) -> float:
    """Seconds until two consecutive screenshots are equal and the 3-D view is not blank."""
    prev = None
    while time.monotonic() - t0 < timeout_s:
        img = _rgb(page.screenshot())  # type: ignore[attr-defined]
        h, w, _ = img.shape
        centre = img[h // 4: 3 * h // 4, w // 8: 5 * w // 8].astype(int)
        drawn = (np.abs(centre - centre[0, 0]).sum(axis=2) > 60).mean() > 0.02
        if drawn and prev is not None and np.array_equal(prev, img):
            return time.monotonic() - t0
        prev = img
        time.sleep(0.5)
    return float("nan")


def save_png(shot: PageShot, path: str | Path) -> Path:
    """Write the screenshot (refuses to overwrite an existing file)."""
    p = Path(path)
    with open(p, "xb") as fh:
        fh.write(shot.png)
    return p
