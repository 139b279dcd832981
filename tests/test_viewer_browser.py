"""``articutool view`` in a real browser: the server runs as its own process, Debian's
headless Chromium loads the page (WebGL through SwiftShader), and the screenshots must show
the model — robot pixels that vanish when the page's "show robot" box is unticked — with no
console errors."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser")
pytest.importorskip("playwright")

from articutool.viewer.snapshot import chromium_path, screenshot
from conftest import free_port

pytestmark = pytest.mark.skipif(
    chromium_path() is None,
    reason="Chromium is not installed (Debian package `chromium`; `make` installs it)")

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@contextmanager
def viewer(*args: str) -> Iterator[str]:
    """Start ``articutool view`` as a process; yields the URL it printed."""
    p = subprocess.Popen([sys.executable, "-m", "articutool", "view", "--port",
                          str(free_port()), "--duration", "300", *args],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = None
        assert p.stdout is not None
        for line in p.stdout:
            if line.startswith("viewer: http://127.0.0.1:"):
                url = line.split()[1]
                break
        assert url is not None, p.stderr.read() if p.stderr else ""
        yield url
    finally:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    assert p.returncode == 0, p.returncode  # a clean stop


def _robot_pixels(img: np.ndarray) -> int:
    """Pixels of the robot's dark grey (MJCF rgba 0.25 0.25 0.28, shaded) in the 3-D view,
    left of the control panel and below the notifications."""
    h, w, _ = img.shape
    region = img[h // 5:, : int(0.65 * w)].astype(int)
    grey = (region.max(axis=2) < 110) & (region.max(axis=2) - region.min(axis=2) < 25)
    return int(grey.sum())


def test_page_draws_the_robot_and_scene_without_console_errors(tmp_path: Path) -> None:
    with viewer() as url:
        shown, hidden = screenshot(url, width=960, height=640,
                                   actions=[("click_label", "show robot")])
    (tmp_path / "shown.png").write_bytes(shown.png)
    (tmp_path / "hidden.png").write_bytes(hidden.png)
    assert shown.console_errors == [] and hidden.console_errors == []
    # The scene is drawn: most of the 3-D view is not the page background.
    img = shown.image.astype(int)
    h, w, _ = img.shape
    view = img[h // 5:, : int(0.65 * w)]
    assert (np.abs(view - np.array([255, 255, 255])).sum(axis=2) > 30).mean() > 0.3
    # The robot is drawn where it stands, and it is what disappears when hidden.
    n_shown, n_hidden = _robot_pixels(shown.image), _robot_pixels(hidden.image)
    assert n_shown > 3000, n_shown
    assert n_hidden < 0.1 * n_shown, (n_shown, n_hidden)


@pytest.mark.slow
def test_plan_page_loads_without_console_errors() -> None:
    with viewer("--plan", str(EXAMPLES / "transport_flip.json"), "--at", "2.2") as url:
        (shot,) = screenshot(url, width=960, height=640)
    assert shot.console_errors == []
    assert _robot_pixels(shot.image) > 3000
    # The failure marker (a red sphere, highlight colour 230, 20, 20) is on the page.
    img = shot.image.astype(int)
    red = (img[..., 0] > 180) & (img[..., 1] < 70) & (img[..., 2] < 70)
    assert red.sum() > 20


