"""Soak: the real tool for a long time against a random, hostile client.

Runs ``articutool tool`` (simulated wrist, the real 50 Hz runtime, paired: mutual TLS on one
port, plain loopback TCP on another) and, from this process, a paired client issuing random
commands: valid ones (modes with offsets, primitives, trajectories, cancel, clear-fault,
take-over/release), invalid ones (unknown primitives, parameters and offsets out of range,
trajectories outside the limits), signed garbage payloads on every command endpoint,
unsigned commands over the plain port, and link drops (the client closes, or goes silent
without releasing its lease, and comes back). Every ``--sample`` seconds it records the
tool's loop statistics (overruns, maximum period, jitter), mode, fault and RSS; every
command's outcome is recorded. Writes JSON (rewritten every minute, so an interrupted soak
keeps its figures)::

    .venv/bin/python benchmarks/soak.py --duration 3600 --out results/soak.json   # make soak
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import random
import subprocess
import sys
import time
import uuid
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from articutool.link.client import ArticutoolClient, LinkError
from articutool.link.config import LinkConfig
from articutool.link.transport import Names
from articutool.spec import load_spec
from articutool.trajectory import JointTrajectory
from paired_tool import free_port, rss_mb, start_paired_tool


def _num(v: float) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


class Soak:
    """The random client and the records."""

    def __init__(self, a: argparse.Namespace) -> None:
        self.a = a
        self.rng = random.Random(a.seed)
        self.spec = load_spec()
        self.plain = free_port()
        started = start_paired_tool("articutool-soak-", plain_port=self.plain)
        self.tmp, self.tool, self.cfg = started.folder, started.proc, started.pc_config
        self.client: ArticutoolClient | None = None
        self.outcomes: list[dict[str, Any]] = []
        self.samples: list[dict[str, Any]] = []
        self.faults: list[dict[str, Any]] = []
        self.t0 = time.monotonic()
        self._last_fault = ""

    # ---------------------------------------------------------------- helpers --
    def now(self) -> float:
        return round(time.monotonic() - self.t0, 3)

    def connect(self) -> ArticutoolClient:
        if self.client is None:
            self.client = ArticutoolClient(self.cfg)
            if not self.client.wait_for_tool(30.0):
                raise SystemExit("tool not heard within 30 s")
        return self.client

    def record(self, kind: str, cmd: str, args: Any, fn: Any) -> None:
        t = time.monotonic()
        try:
            out = fn()
            if out is None:
                ok, msg = True, "sent"
            elif isinstance(out, tuple):
                ok, msg = out
            elif isinstance(out, bool):
                ok, msg = out, "cancelling" if out else "nothing to cancel"
            else:
                ok, msg = bool(out.success), out.message
        except (LinkError, ValueError, TimeoutError) as err:
            ok, msg = False, f"{type(err).__name__}: {err}"
        self.outcomes.append({"t": self.now(), "kind": kind, "cmd": cmd, "args": args,
                              "ok": bool(ok), "message": str(msg)[:200],
                              "latency_s": round(time.monotonic() - t, 4)})

    def sample(self) -> None:
        c = self.connect()
        st = c.latest_state()
        row: dict[str, Any] = {"t": self.now(), "rss_mb": rss_mb(self.tool.pid)}
        if st is not None:
            row.update({"mode": st.mode.name, "fault": st.fault,
                        "loop_overruns": st.loop_overruns,
                        "loop_period_mean_s": _num(st.loop_period_mean),
                        "loop_jitter_s": _num(st.loop_jitter),
                        "loop_period_max_s": _num(st.extra.get("loop_period_max", math.nan)),
                        "tick_compute_max_s": _num(st.extra.get("tick_compute_max_s",
                                                                math.nan)),
                        "faults_total": st.extra.get("faults_total"),
                        "link": {k[5:]: v for k, v in st.extra.items()
                                 if k.startswith("link_")}})
            if st.fault and st.fault != self._last_fault:
                self.faults.append({"t": self.now(), "fault": st.fault})
            self._last_fault = st.fault
        self.samples.append(row)

    # --------------------------------------------------------------- commands --
    def _offsets(self, valid: bool) -> tuple[float, float]:
        if valid:
            return round(self.rng.uniform(-10, 10), 2), round(self.rng.uniform(-10, 10), 2)
        return round(self.rng.choice([-1, 1]) * self.rng.uniform(200, 1e4), 1), 0.0

    def _trajectory(self, valid: bool) -> JointTrajectory:
        c = self.connect()
        st = c.latest_state()
        q = np.array(st.position if st is not None else (0.0, 0.0))
        n = self.rng.randint(2, 20)
        times = np.linspace(0.5, 0.5 + 0.1 * n, n)
        amp = 0.2 if valid else 50.0
        pos = q + amp * np.outer(np.sin(np.linspace(0, math.pi, n)), [1.0, 0.5])
        return JointTrajectory(tuple(st.joint_names) if st else ("pitch", "roll"), times, pos,
                               np.zeros_like(pos))

    def step(self) -> None:
        c = self.connect()
        r = self.rng.random()
        prims = [("TWIRL_CW", [0.5, 2.0]), ("TWIRL_CCW", [0.5, 2.0]), ("HOMING", [1.0]),
                 ("TILT", [0.3, 1.0, 0.3]), ("VIBRATE_ROLL", [5.0, 0.05, 1.0])]
        bad_prims = [("NOPE", []), ("TWIRL_CW", [-1.0, 2.0]), ("HOMING", [1e6]),
                     ("TILT", [1e3, 1.0, 0.3]), ("VIBRATE_ROLL", [])]
        if r < 0.15:
            off = self._offsets(True)
            self.record("valid", "mode leveling", off, lambda: c.set_mode("leveling", *off))
        elif r < 0.30:
            self.record("valid", "mode disabled", None, lambda: c.set_mode("disabled"))
        elif r < 0.45:
            name, params = self.rng.choice(prims)
            self.record("valid", f"primitive {name}", params,
                        lambda: c.run_primitive(name, params, timeout=15.0))
        elif r < 0.52:
            self.record("valid", "trajectory", None,
                        lambda: c.follow_trajectory(self._trajectory(True)))
        elif r < 0.55:
            self.record("valid", "clear-fault", None, c.clear_fault)
        elif r < 0.58:
            self.record("valid", "cancel", None, c.cancel)
        elif r < 0.60:
            self.record("valid", "take-over", None, c.take_over)
        elif r < 0.66:
            off = self._offsets(False)
            self.record("invalid", "mode leveling", off, lambda: c.set_mode("leveling", *off))
        elif r < 0.72:
            name, params = self.rng.choice(bad_prims)
            self.record("invalid", f"primitive {name}", params,
                        lambda: c.run_primitive(name, params, timeout=5.0))
        elif r < 0.75:
            self.record("invalid", "trajectory", None,
                        lambda: c.follow_trajectory(self._trajectory(False)))
        elif r < 0.85:
            self.garbage(c)
        elif r < 0.92:
            self.unsigned()
        elif r < 0.96:
            self.record("drop", "close and reconnect", None, self.reconnect)
        else:
            self.record("drop", "silent (no release) and reconnect", None, self.silent_drop)

    def garbage(self, c: ArticutoolClient) -> None:
        n = Names(self.cfg.namespace, self.cfg.tool_id)
        ep = self.rng.choice([n.set_orientation_control, n.send_goal, n.cancel_goal,
                              n.clear_fault, n.take_over, n.joint_trajectory,
                              n.client_heartbeat])
        blob = self.rng.randbytes(self.rng.randint(0, 300))
        if self.rng.random() < 0.5:
            blob = b"\x00\x01\x00\x00" + blob

        def send() -> tuple[bool, str]:
            if ep.service:
                try:
                    c.transport.call(ep, blob, 0.5)
                    return True, "answered"
                except TimeoutError:
                    return False, "no reply (dropped)"
            c.transport.publish(ep, blob)
            return True, "published"
        self.record("garbage", f"garbage on {ep.name.rsplit('/', 1)[-1]}", len(blob), send)

    def unsigned(self) -> None:
        plain = LinkConfig(connect=(f"tcp/127.0.0.1:{self.plain}",), listen=(),
                           tool_id=self.cfg.tool_id, tool_timeout=1.0)
        with ArticutoolClient(plain, sender="pc-1") as evil:
            if not evil.wait_for_tool(5.0):
                self.outcomes.append({"t": self.now(), "kind": "unsigned", "cmd": "connect",
                                      "args": None, "ok": False, "message": "not heard",
                                      "latency_s": 0.0})
                return
            self.record("unsigned", "mode leveling", None, lambda: evil.set_mode("leveling"))
            self.record("unsigned", "primitive HOMING", [1.0],
                        lambda: evil.run_primitive("HOMING", [1.0], timeout=3.0))

    def reconnect(self) -> tuple[bool, str]:
        if self.client is not None:
            self.client.close()
            self.client = None
        self.connect()
        return True, "reconnected"

    def silent_drop(self) -> tuple[bool, str]:
        c = self.client
        if c is not None:  # heartbeat stops; the transport closes without a release
            c._stop.set()
            c._beat.join(timeout=2)
            for h in c._handles:
                h.close()
            c.transport.close()
            self.client = None
        time.sleep(self.cfg.client_timeout + 0.5)  # the lease expires
        self.connect()
        return True, "reconnected after silence"

    # ---------------------------------------------------------------- summary --
    def summary(self, done: bool) -> dict[str, Any]:
        by = Counter((o["kind"], o["cmd"], o["ok"]) for o in self.outcomes)
        periods = [s["loop_period_max_s"] for s in self.samples
                   if s.get("loop_period_max_s") is not None]
        rss = [s["rss_mb"] for s in self.samples if math.isfinite(s["rss_mb"])]
        over = [s["loop_overruns"] for s in self.samples if "loop_overruns" in s]
        return {
            "command": "python benchmarks/soak.py " + " ".join(sys.argv[1:]),
            "complete": done, "seconds": self.now(), "seed": self.a.seed,
            "machine": platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "loop": {"overruns": (over[-1] - over[0]) if over else None,
                     "period_max_s": max(periods) if periods else None,
                     "period_mean_s": self.samples[-1].get("loop_period_mean_s")
                     if self.samples else None,
                     "jitter_s": self.samples[-1].get("loop_jitter_s") if self.samples
                     else None,
                     "tick_compute_max_s": self.samples[-1].get("tick_compute_max_s")
                     if self.samples else None},
            "memory": {"rss_mb_first": rss[0] if rss else None,
                       "rss_mb_last": rss[-1] if rss else None,
                       "rss_mb_max": max(rss) if rss else None},
            "faults": self.faults,
            "link_counters": self.samples[-1].get("link") if self.samples else None,
            "commands": len(self.outcomes),
            # Safety: none of these may have succeeded.
            "invalid_accepted": sum(o["ok"] for o in self.outcomes if o["kind"] == "invalid"
                                    and o["cmd"] != "trajectory"),
            "unsigned_accepted": sum(o["ok"] for o in self.outcomes if o["kind"] == "unsigned"),
            "outcome_counts": [{"kind": k, "cmd": c, "ok": ok, "n": n}
                               for (k, c, ok), n in sorted(by.items())],
            "tool_exit_code": self.tool.poll(),
            "samples": self.samples, "outcomes": self.outcomes}

    def write(self, done: bool) -> None:
        if self.a.out:
            tmp = Path(self.a.out + ".tmp")
            tmp.write_text(json.dumps(self.summary(done), indent=1) + "\n")
            tmp.replace(self.a.out)

    def run(self) -> dict[str, Any]:
        try:
            self.connect()
            end = self.t0 + self.a.duration
            next_sample, next_write = time.monotonic(), time.monotonic() + 60
            while time.monotonic() < end:
                if self.tool.poll() is not None:
                    self.faults.append({"t": self.now(), "fault": "tool process exited "
                                        f"with {self.tool.returncode}"})
                    break
                self.step()
                time.sleep(self.rng.uniform(0.0, self.a.pause))
                if time.monotonic() >= next_sample:
                    self.sample()
                    next_sample += self.a.sample
                if time.monotonic() >= next_write:
                    self.write(False)
                    next_write += 60
            self.sample()
        finally:
            if self.client is not None:
                self.client.close()
            self.tool.terminate()
            try:
                self.tool.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.tool.kill()
        self.write(True)
        return self.summary(True)


def main(argv: list[str] | None = None) -> int:
    """Run the soak; print the summary (without the per-sample and per-command lists)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=3600.0, help="seconds (default 3600)")
    p.add_argument("--sample", type=float, default=5.0, help="seconds between loop samples")
    p.add_argument("--pause", type=float, default=0.2, help="max pause between commands (s)")
    p.add_argument("--seed", type=int, default=int(uuid.uuid4().int % 2**31))
    p.add_argument("--out", default=None, help="JSON file (rewritten every minute)")
    a = p.parse_args(argv)
    if not a.duration > 0:
        print(f"error: --duration must be > 0 seconds; got {a.duration}", file=sys.stderr)
        return 2
    s = Soak(a).run()
    print(json.dumps({k: v for k, v in s.items() if k not in ("samples", "outcomes")},
                     indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
