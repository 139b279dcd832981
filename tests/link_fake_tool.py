"""A fake ToolAPI whose primitives progress over time, and a script serving it over Zenoh.

Used by the link tests in-process (MemoryTransport) and as the tool process of the
two-process tests::

    python tests/link_fake_tool.py --listen tcp/127.0.0.1:PORT [--policy cancel]
        [--link-config FILE] [--tool-id NAME] [--connect ENDPOINT] [--tick-hz HZ]

With ``--tick-hz`` the tool has a loop, as the runtime: the server's commands run one per
tick at that rate (else a server thread runs them as they come).

Primitives: ``TWIRL [turns]`` (1 parameter in [-2, 2], rolls that many turns in
``TWIRL_S`` seconds), ``SLOW`` (no parameters, 5 s of pitch motion, for cancel tests) and
``HOMING [speed]`` (both joints to zero at ``speed`` rad/s in (0, 4]; at home it is done at
once, with the same result every time, as the runtime's HOMING).
Primitives are refused while LEVELING, while another runs, for unknown names and bad
parameters, with messages like the runtime's. On exit (stdin closed) it prints
``CALLS`` and the API calls it received, so tests can check what reached the tool.
"""

from __future__ import annotations

import math
import sys
import threading
import time

from articutool.tool.api import Mode, PrimitiveStatus, ToolState
from articutool.trajectory import JointTrajectory

TWIRL_S = 0.6
SLOW_S = 5.0


class FakeTool:
    """Implements ToolAPI with simple timed motion (no control loop needed)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.mode = Mode.DISABLED
        self.offsets = (0.0, 0.0)
        self.q0 = (0.1, 0.2)
        self._prim: tuple[str, float, tuple[float, float], tuple[float, float]] | None = None
        self._last: PrimitiveStatus | None = None
        self._cancelled = False
        self.trajectories: list[JointTrajectory] = []
        self.start_delays: list[float] = []
        self.calls: list[str] = []

    def set_mode(self, mode: Mode, pitch_offset_deg: float = 0.0,
                 roll_offset_deg: float = 0.0,
                 target_xyzw: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0)) -> tuple[bool, str]:
        with self._lock:
            self.calls.append(f"set_mode {mode.name}")
            if abs(pitch_offset_deg) > 90 or abs(roll_offset_deg) > 90:
                return False, "pitch_offset/roll_offset must be within [-90, 90] degrees"
            self._abort_locked("aborted by mode change")
            self.mode, self.offsets = mode, (pitch_offset_deg, roll_offset_deg)
            return True, f"mode {mode.name}"

    def clear_fault(self) -> tuple[bool, str]:
        with self._lock:
            self.calls.append("clear_fault")
            return False, "no fault to clear"

    def start_primitive(self, name: str, parameters: list[float]) -> tuple[bool, str]:
        with self._lock:
            self._update_locked()
            self.calls.append(f"start {name}")
            if self.mode == Mode.LEVELING:
                return False, "refused: leveling is active; disable it first"
            if self._prim is not None:
                return False, f"busy: primitive {self._prim[0]} is running"
            if name == "TWIRL":
                if len(parameters) != 1 or not -2 <= parameters[0] <= 2:
                    return False, "TWIRL takes 1 parameter: turns in [-2, 2]"
                goal = (self.q0[0], self.q0[1] + 2 * math.pi * parameters[0])
                dur = TWIRL_S
            elif name == "HOMING":
                if len(parameters) != 1 or not 0 < parameters[0] <= 4:
                    return False, "HOMING takes 1 parameter: speed_rad_s in (0, 4]"
                goal = (0.0, 0.0)
                dur = max(abs(v) for v in self.q0) / parameters[0]
            elif name == "SLOW":
                if parameters:
                    return False, "SLOW takes no parameters"
                goal, dur = (self.q0[0] + 0.5, self.q0[1]), SLOW_S
            else:
                return False, f"unknown primitive {name!r}; known: TWIRL, SLOW, HOMING"
            self._prim = (name, time.monotonic(), self.q0, goal)
            self._dur = dur
            self._cancelled = False
            self.mode = Mode.PRIMITIVE
            return True, "started"

    def _abort_locked(self, why: str) -> None:
        if self._prim is not None:
            name, *_ = self._prim
            q = self._q_locked()
            self._last = PrimitiveStatus(name, self._pct_locked(), why, q, True, False, why, q)
            self.q0, self._prim = q, None
            self.mode = Mode.DISABLED

    def _pct_locked(self) -> float:
        assert self._prim is not None
        if self._dur <= 0:  # nothing to do: done at once
            return 100.0
        return min(100.0, 100.0 * (time.monotonic() - self._prim[1]) / self._dur)

    def _q_locked(self) -> tuple[float, float]:
        assert self._prim is not None
        _, _, a, b = self._prim
        s = self._pct_locked() / 100.0
        return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]))

    def _update_locked(self) -> None:
        if self._prim is None:
            return
        name, _, _, goal = self._prim
        if self._pct_locked() >= 100.0:
            self._last = PrimitiveStatus(name, 100.0, "done", goal, True, True,
                                         f"{name} complete", goal)
            self.q0, self._prim, self.mode = goal, None, Mode.DISABLED
        else:
            self._last = PrimitiveStatus(name, self._pct_locked(), f"{name} running",
                                         self._q_locked(), False)

    def primitive_status(self) -> PrimitiveStatus | None:
        with self._lock:
            self._update_locked()
            return self._last

    def cancel_primitive(self) -> bool:
        with self._lock:
            self._update_locked()
            self.calls.append("cancel")
            if self._prim is None:
                return False
            self._abort_locked("cancelled")
            return True

    def follow_trajectory(self, trajectory: JointTrajectory,
                          start_delay: float = 0.0) -> tuple[bool, str]:
        with self._lock:
            if list(trajectory.joint_names) != ["pitch", "roll"]:
                return False, "joint_names must be ['pitch', 'roll']"
            self.trajectories.append(trajectory)
            self.start_delays.append(start_delay)
            self.mode = Mode.TRAJECTORY
            return True, "following"

    def state(self) -> ToolState:
        with self._lock:
            self._update_locked()
            q = self._q_locked() if self._prim is not None else self.q0
            return ToolState(stamp=time.monotonic(), mode=self.mode,
                             joint_names=("pitch", "roll"), position=q, velocity=(0.0, 0.0),
                             orientation_wxyz=(1.0, 0.0, 0.0, 0.0),
                             angular_velocity=(0.0, 0.0, 0.01),
                             linear_acceleration=(0.0, 0.0, 9.81), battery_voltage=11.9,
                             loop_period_mean=0.02, loop_jitter=0.0005, loop_overruns=0)


class TickingTool(FakeTool):
    """A FakeTool with a loop of its own: one link command per tick, as ToolRuntime."""

    def __init__(self, hz: float) -> None:
        super().__init__()
        self._work = None
        self._period = 1.0 / hz
        threading.Thread(target=self._loop, daemon=True).start()

    def set_link_work(self, work):  # type: ignore[no-untyped-def]
        self._work = work

    def _loop(self) -> None:
        while True:
            time.sleep(self._period)
            work = self._work
            if work is not None:
                work()


def main(argv: list[str]) -> int:
    """Serve a FakeTool until stdin closes or SIGTERM."""
    import argparse
    import signal

    from articutool.link.config import LinkConfig
    from articutool.link.server import serve_forever

    p = argparse.ArgumentParser()
    p.add_argument("--listen", action="append", required=True)
    p.add_argument("--connect", action="append", default=[])
    p.add_argument("--policy", default="continue")
    p.add_argument("--client-timeout", type=float, default=2.0)
    p.add_argument("--link-config", default=None)
    p.add_argument("--tool-id", default=None)
    p.add_argument("--tick-hz", type=float, default=None)
    a = p.parse_args(argv)
    from articutool.link.config import load_config

    base = load_config(a.link_config) if a.link_config else LinkConfig()
    cfg = base.replace(listen=tuple(a.listen), connect=tuple(a.connect),
                       link_loss_policy=a.policy, client_timeout=a.client_timeout,
                       tool_id=a.tool_id or base.tool_id)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    tool = FakeTool() if a.tick_hz is None else TickingTool(a.tick_hz)

    def watch_stdin() -> None:
        sys.stdin.read()
        stop.set()
    threading.Thread(target=watch_stdin, daemon=True).start()
    serve_forever(tool, cfg, stop, loop=tool if isinstance(tool, TickingTool) else None)
    print("CALLS " + ";".join(tool.calls), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
