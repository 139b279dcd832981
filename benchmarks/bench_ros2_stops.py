"""Stops and cancels at the ROS 2 door under a flood of bad calls: how many are answered, and
how fast.

Four processes: the real tool (``articutool tool --no-level``, simulated wrist, paired,
loopback TLS), ``articutool ros2`` forwarding to it, a flooder (``tests/ros2_flooder.py``: a
plain rclpy node sending ``--rate`` bad calls per second round robin over mode 7, a 500°
offset, NaN, unknown primitives, cancels of unknown goals, calibration and empty
verifications), and this process as a plain rclpy client that, while the flood runs:

- calls ``/articutool/stop`` ``--stops`` times, ``--gap`` s apart (the dedicated stop);
- calls ``/articutool/set_orientation_control`` with DISABLED as often (ADA's way to stop,
  on the service the flood hits);
- starts ``--goals`` slow primitives and cancels each (``ExecuteArticutoolPrimitive``);
- sends a burst of ``--burst`` cancels of unknown goals at once.

A call counts as answered when its reply arrives within ``--deadline`` s; latency is the
round trip (``time.perf_counter``, wall clock). Scenarios: ``quiet`` (no flood) and
``flood``. The node's CPU time (``/proc``) and the load average are recorded. Writes JSON::

    .venv/bin/python benchmarks/bench_ros2_stops.py --out results/ros2_stops.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).parent))
from paired_tool import start_paired_tool  # noqa: E402

FLOODER = ROOT / "tests" / "ros2_flooder.py"


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of ``pid`` (Linux)."""
    try:
        f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
    except OSError:
        return float("nan")


def _lat(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"p50_ms": None, "p99_ms": None, "max_ms": None}
    a = np.asarray(values) * 1e3
    return {"p50_ms": round(float(np.percentile(a, 50)), 2),
            "p99_ms": round(float(np.percentile(a, 99)), 2), "max_ms": round(float(a.max()), 2)}


class Client:
    """The plain rclpy client (rclpy's own Client/ActionClient only)."""

    def __init__(self, domain: int) -> None:
        import rclpy
        from action_msgs.srv import CancelGoal
        from articutool_interfaces.action import ExecuteArticutoolPrimitive
        from articutool_interfaces.srv import SetOrientationControl
        from rclpy.action import ActionClient
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile
        from std_srvs.srv import Trigger

        self.rclpy = rclpy
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = rclpy.create_node("bench_client", context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.A, self.SOC, self.Trigger, self.CancelGoal = (ExecuteArticutoolPrimitive,
                                                          SetOrientationControl, Trigger,
                                                          CancelGoal)
        # deep reply queues: the client's own history must not be what loses a reply
        deep = QoSProfile(depth=1000)
        self.stop = self.node.create_client(Trigger, "/articutool/stop", qos_profile=deep)
        self.soc = self.node.create_client(SetOrientationControl,
                                           "/articutool/set_orientation_control",
                                           qos_profile=deep)
        self.cancel = self.node.create_client(
            CancelGoal, "/orientation_control/execute_primitive/_action/cancel_goal",
            qos_profile=deep)
        self.action = ActionClient(self.node, ExecuteArticutoolPrimitive,
                                   "/orientation_control/execute_primitive")
        for c in (self.stop, self.soc, self.cancel):
            assert c.wait_for_service(timeout_sec=60), c.srv_name
        assert self.action.wait_for_server(timeout_sec=60)

    def spin_until(self, cond: Any, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.01)
            if cond():
                return True
        return False

    def calls(self, client: Any, make: Any, n: int, gap: float, deadline: float
              ) -> dict[str, Any]:
        """``n`` calls ``gap`` s apart, each waited for up to ``deadline`` s from its send."""
        sent: list[tuple[float, Any]] = []
        lat: list[float] = []
        ok = 0
        for _ in range(n):
            f = client.call_async(make())
            f.add_done_callback(lambda fut: setattr(fut, "_t_done", time.perf_counter()))
            sent.append((time.perf_counter(), f))
            if gap:
                self.spin_until(lambda: False, gap)
        end = time.monotonic() + deadline
        self.spin_until(lambda: all(f.done() for _, f in sent) or time.monotonic() > end,
                        deadline + 1)
        for t0, f in sent:
            if f.done():
                r = f.result()
                lat.append(getattr(f, "_t_done", time.perf_counter()) - t0)
                ok += bool(getattr(r, "success", True))
        return {"sent": n, "answered": sum(f.done() for _, f in sent), "success": ok,
                **_lat(lat)}

    def goals(self, n: int, deadline: float) -> dict[str, Any]:
        """Start ``n`` slow twirls and cancel each once it runs."""
        from action_msgs.msg import GoalStatus
        answered, canceled, lat = 0, 0, []
        for _ in range(n):
            fut = self.action.send_goal_async(self.A.Goal(primitive_name="TWIRL_CW",
                                                          parameters=[1.0, 0.5]))
            if not self.spin_until(fut.done, deadline) or not fut.result().accepted:
                continue
            handle = fut.result()
            self.spin_until(lambda: False, 0.3)
            t0 = time.perf_counter()
            cf = handle.cancel_goal_async()
            if self.spin_until(cf.done, deadline):
                answered += 1
                lat.append(time.perf_counter() - t0)
            rf = handle.get_result_async()
            if self.spin_until(rf.done, deadline):
                canceled += rf.result().status == GoalStatus.STATUS_CANCELED
        return {"sent": n, "answered": answered, "ended_canceled": canceled, **_lat(lat)}

    def burst(self, n: int, deadline: float) -> dict[str, Any]:
        def make() -> Any:
            req = self.CancelGoal.Request()
            req.goal_info.goal_id.uuid = list(uuid.uuid4().bytes)
            return req
        return self.calls(self.cancel, make, n, 0.0, deadline)

    def close(self) -> None:
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.ctx)


def scenario(name: str, rate: float, client: Client, env: dict[str, str], node_pid: int,
             args: argparse.Namespace) -> dict[str, Any]:
    flooder = None
    if rate > 0:
        flooder = subprocess.Popen([sys.executable, str(FLOODER), "--rate", str(rate),
                                    "--seconds", "600"], env=env, text=True,
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        assert flooder.stdout is not None
        assert flooder.stdout.readline().strip() == "READY", "flooder did not start"
        client.spin_until(lambda: False, 1.0)
    cpu0, t0, load0 = _cpu_s(node_pid), time.monotonic(), os.getloadavg()
    soc = client.SOC
    out: dict[str, Any] = {
        "flood_calls_per_s": rate,
        "stop_service": client.calls(client.stop, client.Trigger.Request, args.stops, args.gap,
                                     args.deadline),
        "disabled_on_set_orientation_control": client.calls(
            client.soc, lambda: soc.Request(control_mode=0), args.stops, args.gap,
            args.deadline),
        "cancels_of_running_goals": client.goals(args.goals, args.deadline),
        "cancel_burst": client.burst(args.burst, args.deadline),
    }
    wall = time.monotonic() - t0
    out["node_cpu_s"] = round(_cpu_s(node_pid) - cpu0, 2)
    out["wall_s"] = round(wall, 2)
    out["loadavg_start"] = load0
    if flooder is not None:
        text, _ = flooder.communicate(input="", timeout=120)
        f = text.split()
        if f and f[0] == "SENT":
            out["flood"] = {"sent": int(f[1]), "answered": int(f[3]), "seconds": float(f[4])}
    print(name, json.dumps(out), flush=True)
    return out


def start_graph(prefix: str, stderr: Any = subprocess.DEVNULL
                ) -> tuple[dict[str, str], Any, subprocess.Popen[str]]:
    """A random domain's environment (host-only), the paired tool (``start_paired_tool``) and
    ``articutool ros2`` serving it, once it says so."""
    domain = random.Random(os.getpid()).randint(120, 220)
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    tool = start_paired_tool(prefix)
    node = subprocess.Popen(
        [sys.executable, "-m", "articutool", "ros2", "--link-config",
         str(tool.folder / "pc-1" / "link.toml"), "--connect", tool.pc_config.connect[0],
         "--tool-id", "wrist-1", "--wait", "60"],
        env=env, text=True, stdout=subprocess.PIPE, stderr=stderr)
    assert node.stdout is not None
    line = node.stdout.readline()
    if "serving" not in line:
        stop_all((node, tool.proc))
        raise SystemExit(f"node did not start: {line!r}")
    return env, tool, node


def stop_all(procs: Any) -> None:
    """SIGINT each process, then SIGKILL what has not ended within 30 s."""
    for p in procs:
        p.send_signal(2)
        try:
            p.wait(30)
        except subprocess.TimeoutExpired:
            p.kill()


def write_result(args: argparse.Namespace, clock: str, **fields: Any) -> None:
    """``args.out``: the machine, the clocks named, the settings and ``fields``, as JSON."""
    doc = {"machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                       "cpus": os.cpu_count()}, "clock": clock, "settings": vars(args), **fields}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {args.out}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--stops", type=int, default=50)
    ap.add_argument("--gap", type=float, default=0.1)
    ap.add_argument("--goals", type=int, default=5)
    ap.add_argument("--burst", type=int, default=600)
    ap.add_argument("--deadline", type=float, default=15.0)
    ap.add_argument("--out", default="results/ros2_stops.json")
    args = ap.parse_args()
    env, tool, node = start_graph("ros2-stops-")
    client = Client(int(env["ROS_DOMAIN_ID"]))
    try:
        runs = {"quiet": scenario("quiet", 0, client, env, node.pid, args),
                "flood": scenario("flood", args.rate, client, env, node.pid, args)}
    finally:
        client.close()
        stop_all((node, tool.proc))
    write_result(args, "latency: wall clock (perf_counter) round trip; node_cpu_s: /proc CPU "
                       "time", runs=runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
