"""The README's pictures of ``articutool view``: a plan and a replayed run (headless Chromium).

    .venv/bin/python examples/view_screenshots.py --out docs

Writes ``view_plan.png`` (``articutool view --plan examples/transport_flip.json --at 2.2``:
an infeasible transport, its tip path coloured by the velocity margin and its first failing
waypoint marked) and ``view_replay.png`` (a locked-wrist carry of 8 g of water recorded with
``articutool sim --food water --script carry --no-level --load 8 --record run.npz`` and
replayed with ``articutool view --recording run.npz --at 6.0``: water on the spoon, spill
markers, telemetry plots). Existing files are never overwritten.
"""

from __future__ import annotations

import argparse
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

from articutool.viewer.snapshot import save_png, screenshot

HERE = Path(__file__).resolve().parent


def _shoot(out: Path, *view_args: str) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    p = subprocess.Popen([sys.executable, "-m", "articutool", "view", "--port", str(port),
                          "--duration", "600", *view_args], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout is not None
        url = next(line.split()[1] for line in p.stdout if line.startswith("viewer: "))
        (shot,) = screenshot(url, width=1280, height=800)
        if shot.console_errors:
            print(f"console errors: {shot.console_errors}", file=sys.stderr)
        save_png(shot, out)
        print(f"{out} ({shot.seconds_to_stable:.1f} s to a stable frame)")
    finally:
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=30)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE.parent / "docs")
    args = ap.parse_args()
    plan_png, replay_png = args.out / "view_plan.png", args.out / "view_replay.png"
    for f in (plan_png, replay_png):
        if f.exists():
            print(f"error: {f} exists (nothing is overwritten)", file=sys.stderr)
            return 2
    _shoot(plan_png, "--plan", str(HERE / "transport_flip.json"), "--at", "2.2")
    with tempfile.TemporaryDirectory() as d:
        rec = Path(d) / "run.npz"
        subprocess.run([sys.executable, "-m", "articutool", "sim", "--food", "water",
                        "--script", "carry", "--no-level", "--load", "8", "--record", str(rec)],
                       check=True)
        _shoot(replay_png, "--recording", str(rec), "--at", "6.0")
    return 0


if __name__ == "__main__":
    sys.exit(main())
