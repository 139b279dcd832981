"""The ROS 2 door: a host-only ``articutool ros2`` that no other host can find or command, and
every call answered under a flood of bad ones.

- the Fast DDS profile the node applies, its private file, the process's socket list (pure);
- the host-only node's sockets are all on loopback; a socket bound beyond loopback makes it
  refuse to run (exit 2, naming it);
- a second network namespace joined by a veth pair (standing for a second machine) that
  names this host as a static peer on the same domain neither discovers
  ``/articutool/set_orientation_control`` nor gets a LEVELING through, and the tool's mode
  stays DISABLED; with ``--allow-remote-ros-clients`` the same client finds it and levels
  the tool (the harness reaches across). Needs root and ``ip``: skipped, saying why, elsewhere;
- a flood of bad calls and a burst of cancels: every call answered (or refused), and
  ``/articutool/stop`` ends a running primitive meanwhile. Counts only: no timing is asserted.

The tool is the real one (``articutool tool`` on the simulated drivers, paired, loopback TLS);
clients are plain rclpy (``tests/ros2_probe.py``, ``tests/ros2_flooder.py`` and this process).
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import uuid
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from articutool.link.client import ArticutoolClient
from articutool.link.config import load_config
from articutool.link.pairing import pair
from articutool.ros2.host_only import (
    BoundSocket,
    apply_profile,
    exposed,
    process_sockets,
    profile_xml,
)
from articutool.tool.api import Mode
from conftest import free_port, ros_domain_id, wait_until

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
DOMAIN = ros_domain_id(salt=3)
NS = "{http://www.eprosima.com}"
_why = "rclpy and the built articutool_interfaces (make; CPython 3.11 on x86_64 only)"


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("ROS_", "FASTDDS_", "FASTRTPS_"))}
    env.update({"PYTHONPATH": str(SRC), "ROS_DOMAIN_ID": str(DOMAIN),
                "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", **extra})
    return env


# ---------------------------------------------------------------------------- pure --
def _texts(root: ET.Element, path: str) -> list[str]:
    return [e.text or "" for e in root.iter(f"{NS}{path}")]


def test_the_profile_keeps_dds_on_loopback_and_shared_memory() -> None:
    root = ET.fromstring(profile_xml(["127.0.0.2", "10.0.0.7", "localhost", "::1", "pi.local"]))
    assert _texts(root, "useBuiltinTransports") == ["false"]
    assert sorted(_texts(root, "type")) == ["SHM", "UDPv4"]
    white = root.find(f".//{NS}interfaceWhiteList")
    assert white is not None and [a.text for a in white] == ["127.0.0.1"]
    assert root.find(f".//{NS}metatrafficMulticastLocatorList") is None  # no multicast
    unicast = root.find(f".//{NS}metatrafficUnicastLocatorList")
    assert unicast is not None and _texts(unicast, "address") == ["127.0.0.1"]
    peers = root.find(f".//{NS}initialPeersList")
    assert peers is not None and _texts(peers, "address") == ["127.0.0.1", "127.0.0.2"]
    assert root.find(f".//{NS}allocation") is None
    off = ET.fromstring(profile_xml(["127.0.0.2"], discovery=False))
    peers = off.find(f".//{NS}initialPeersList")
    assert peers is not None and len(peers) == 0
    assert _texts(off, "maximum") == ["1"]  # no participant but this one


def test_the_profile_is_written_privately_and_the_environment_points_at_it() -> None:
    env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "127.0.0.3",
           "FASTDDS_BUILTIN_TRANSPORTS": "LARGE_DATA"}
    prof = apply_profile(env)
    try:
        path = Path(env["FASTDDS_DEFAULT_PROFILES_FILE"])
        assert path == prof.path and "127.0.0.3" in path.read_text()
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
        assert stat.S_IMODE(path.parent.stat().st_mode) == 0o700
        assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
        assert env["SKIP_DEFAULT_XML_FILE"] == "1"
        assert "FASTDDS_BUILTIN_TRANSPORTS" not in env
    finally:
        prof.remove()
    assert not path.parent.exists()


def test_the_socket_list_finds_what_is_bound_and_where() -> None:
    opened = []
    try:
        for family, host, kind in ((socket.AF_INET, "127.0.0.1", socket.SOCK_DGRAM),
                                   (socket.AF_INET, "0.0.0.0", socket.SOCK_DGRAM),
                                   (socket.AF_INET, "127.0.0.1", socket.SOCK_STREAM)):
            s = socket.socket(family, kind)
            s.bind((host, 0))
            if kind == socket.SOCK_STREAM:
                s.listen()  # a TCP socket is listed once it listens or connects
            opened.append(s)
        try:
            s6 = socket.socket(socket.AF_INET6, socket.SOCK_DGRAM)
            s6.bind(("::1", 0))
            opened.append(s6)
        except OSError:  # no IPv6 here
            pass
        mine = {BoundSocket(("udp" if s.type == socket.SOCK_DGRAM else "tcp")
                            + ("6" if s.family == socket.AF_INET6 else ""),
                            str(ipaddress.ip_address(s.getsockname()[0])), s.getsockname()[1])
                for s in opened}
        listed = set(process_sockets())
        assert mine <= listed
        wide = [s for s in exposed(listed) if s in mine]
        assert [str(s) for s in wide] == [f"udp 0.0.0.0:{opened[1].getsockname()[1]}"]
        assert str(BoundSocket("udp6", "::", 7)) == "udp6 [::]:7"
    finally:
        for s in opened:
            s.close()


# ----------------------------------------------------------------------- processes --
def _node(extra: list[str], env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "articutool", "ros2", *extra],
                            env=env or _env(), text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)


def _serving(p: subprocess.Popen[str]) -> None:
    assert p.stdout is not None
    line = p.stdout.readline()
    if "serving" not in line:
        p.kill()
        _, err = p.communicate(timeout=30)
        raise AssertionError((line, err))


def _stop(p: subprocess.Popen[str]) -> str:
    if p.poll() is None:
        p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
    return err


def test_the_host_only_node_binds_loopback_only() -> None:
    """Measured from outside the process (its /proc tables); with the flag the same
    environment listens beyond loopback, which the listing sees."""
    pytest.importorskip("rclpy", reason=_why)
    pytest.importorskip("articutool_interfaces.srv", reason=_why)
    for flag, wide in (([], False), (["--allow-remote-ros-clients"], True)):
        p = _node(["--verify-only", *flag])
        try:
            _serving(p)
            socks = process_sockets(p.pid)
        finally:
            _stop(p)
        assert socks and bool(exposed(socks)) is wide, [str(s) for s in socks]


def test_a_socket_beyond_loopback_makes_the_node_refuse(tmp_path: Path) -> None:
    """Anything in the process bound beyond loopback when the participant exists (here a
    UDP socket opened at interpreter start-up) is refused: exit 2 naming it."""
    pytest.importorskip("rclpy", reason=_why)
    pytest.importorskip("articutool_interfaces.srv", reason=_why)
    (tmp_path / "sitecustomize.py").write_text(
        "import socket\n_held = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)\n"
        "_held.bind(('0.0.0.0', 0))\n")
    p = _node(["--verify-only"], _env(PYTHONPATH=f"{tmp_path}{os.pathsep}{SRC}"))
    out, err = p.communicate(timeout=60)
    assert p.returncode == 2, (out, err)
    assert "refusing to run host-only" in err and "udp 0.0.0.0:" in err
    assert "Traceback" not in err and "serving" not in out


# ------------------------------------------------------------- the tool and a node --
class Tool:
    """The real tool on loopback TLS, paired with one PC, and a read-only link client."""

    def __init__(self, folder: Path) -> None:
        tool_id = f"wrist_door_{os.getpid()}"
        pair(folder, tool_id, ["pc_1"])
        self.port = free_port()
        self.pc_cfg = folder / "pc_1" / "link.toml"
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "articutool", "tool", "--no-level", "--link-config",
             str(folder / tool_id / "link.toml"), "--listen", f"tls/127.0.0.1:{self.port}"],
            env=_env(), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        self.link = ArticutoolClient(load_config(self.pc_cfg).replace(
            connect=(f"tls/127.0.0.1:{self.port}",), listen=()))
        assert self.link.wait_for_tool(30), "the tool was not heard"

    def node(self, *extra: str) -> subprocess.Popen[str]:
        p = _node(["--link-config", str(self.pc_cfg), "--connect",
                   f"tls/127.0.0.1:{self.port}", "--wait", "30", *extra])
        _serving(p)
        return p

    def mode(self) -> Mode:
        """The tool's mode from its telemetry (this client commands nothing)."""
        start = self.link.latest_state()
        assert start is not None
        assert wait_until(lambda: self.link.latest_state().stamp > start.stamp + 0.2, 10)
        return self.link.latest_state().mode

    def close(self) -> None:
        self.link.close()
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture(scope="module")
def tool(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Tool]:
    pytest.importorskip("rclpy", reason=_why)
    pytest.importorskip("articutool_interfaces.srv", reason=_why)
    t = Tool(tmp_path_factory.mktemp("door"))
    try:
        yield t
    finally:
        t.close()


# ------------------------------------------------------------ the second "host" --
def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)


@pytest.fixture
def other_host() -> Iterator[tuple[str, str]]:
    """A network namespace joined to this one by a veth pair: (its name, this side's
    address). Removed with every process in it afterwards."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        pytest.skip("creating a network namespace needs root")
    if shutil.which("ip") is None:
        pytest.skip("iproute2's `ip` is not installed")
    pid = os.getpid()
    name, here, there = f"articutool_door_{pid}", f"atd{pid}a", f"atd{pid}b"
    net = f"10.231.{pid % 250}"
    made = _ip("netns", "add", name)
    if made.returncode != 0:
        pytest.skip(f"no network namespaces here: {made.stderr.strip()}")
    try:
        for cmd in (("link", "add", here, "type", "veth", "peer", "name", there),
                    ("link", "set", there, "netns", name),
                    ("addr", "add", f"{net}.1/24", "dev", here), ("link", "set", here, "up"),
                    ("-n", name, "addr", "add", f"{net}.2/24", "dev", there),
                    ("-n", name, "link", "set", there, "up"),
                    ("-n", name, "link", "set", "lo", "up")):
            r = _ip(*cmd)
            assert r.returncode == 0, (cmd, r.stderr)
        yield name, f"{net}.1"
    finally:
        for pid_in in _ip("netns", "pids", name).stdout.split():
            with contextlib.suppress(ProcessLookupError, ValueError):
                os.kill(int(pid_in), signal.SIGKILL)
        _ip("link", "del", here)
        _ip("netns", "del", name)


def _probe(mode: int, netns: str | None = None, peer: str | None = None,
           find: float = 8.0) -> dict[str, Any]:
    env = _env(**({"ROS_STATIC_PEERS": peer} if peer else {}))
    cmd = [sys.executable, str(HERE / "ros2_probe.py"), "--mode", str(mode), "--find",
           str(find), "--answer", "5"]
    if netns is not None:
        cmd = ["ip", "netns", "exec", netns, *cmd]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_another_host_naming_this_one_neither_finds_nor_commands_the_node(
        tool: Tool, other_host: tuple[str, str]) -> None:
    netns, address = other_host
    node = tool.node()
    try:
        assert tool.mode() is Mode.DISABLED
        remote = _probe(1, netns, peer=address)  # LEVELING, from the other "host"
        assert not remote["found"] and not remote["answered"], remote
        assert tool.mode() is Mode.DISABLED
        local = _probe(0)  # the harness: a loopback client finds it and is answered
        assert local["found"] and local["answered"] and local["success"], local
    finally:
        err = _stop(node)
    assert node.returncode == 0, err


def test_with_the_flag_the_other_host_finds_and_commands_it(
        tool: Tool, other_host: tuple[str, str]) -> None:
    """The control: the same client in the same namespace reaches a node opened knowingly."""
    netns, address = other_host
    node = tool.node("--allow-remote-ros-clients")
    try:
        remote = _probe(1, netns, peer=address, find=20.0)
        assert remote["found"] and remote["answered"] and remote["success"], remote
        assert wait_until(lambda: tool.mode() is Mode.LEVELING, 10)
        assert _probe(0, netns, peer=address, find=20.0)["success"]
        assert wait_until(lambda: tool.mode() is Mode.DISABLED, 10)
    finally:
        err = _stop(node)
    assert "warning: --allow-remote-ros-clients" in err


# ------------------------------------------------------------------------ the flood --
def test_every_call_is_answered_under_a_flood_and_the_stop_works(tool: Tool) -> None:
    """200 bad calls (every kind the flooder sends, over 2 s) and a burst of 50 cancels of
    unknown goals from a second client, while a primitive runs: every call and every cancel
    is answered (a refusal is an answer), and ``/articutool/stop`` sent during the flood ends
    the primitive. Counts only."""
    import rclpy
    from action_msgs.msg import GoalStatus
    from action_msgs.srv import CancelGoal
    from articutool_interfaces.action import ExecuteArticutoolPrimitive
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from std_srvs.srv import Trigger

    node = tool.node()
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN)
    client = rclpy.create_node("plain_flood_client", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(client)
    flooder = None
    try:
        action = ActionClient(client, ExecuteArticutoolPrimitive,
                              "/orientation_control/execute_primitive")
        stop = client.create_client(Trigger, "/articutool/stop")
        cancel = client.create_client(
            CancelGoal, "/orientation_control/execute_primitive/_action/cancel_goal",
            qos_profile=QoSProfile(depth=1000))
        assert action.wait_for_server(timeout_sec=30)
        assert stop.wait_for_service(timeout_sec=30) and cancel.wait_for_service(timeout_sec=30)

        def wait(future: Any, timeout: float = 120.0) -> Any:
            ex.spin_until_future_complete(future, timeout_sec=timeout)
            assert future.done(), "no answer"
            return future.result()
        handle = wait(action.send_goal_async(ExecuteArticutoolPrimitive.Goal(
            primitive_name="TWIRL_CW", parameters=[1.0, 0.5])))
        assert handle.accepted
        flooder = subprocess.Popen(
            [sys.executable, str(HERE / "ros2_flooder.py"), "--rate", "100", "--count", "200",
             "--seconds", "600", "--grace", "120"], env=_env(), text=True, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE)
        assert flooder.stdout is not None
        assert flooder.stdout.readline().strip() == "READY"
        burst = []
        for _ in range(50):
            req = CancelGoal.Request()
            req.goal_info.goal_id.uuid = list(uuid.uuid4().bytes)
            burst.append(cancel.call_async(req))
        stopped = wait(stop.call_async(Trigger.Request()))
        assert stopped.success, stopped.message
        result = wait(handle.get_result_async())
        assert result.status != GoalStatus.STATUS_SUCCEEDED  # the stop ended it
        for f in burst:
            assert not wait(f).goals_canceling  # answered: no such goal
        flooder.wait(timeout=300)  # its count sent and answered (stdin kept open)
        out = flooder.stdout.read()
    finally:
        if flooder is not None and flooder.poll() is None:
            flooder.kill()
        client.destroy_node()
        rclpy.try_shutdown(context=ctx)
        err = _stop(node)
    assert node.returncode == 0, err
    sent = out.split()  # SENT n ANSWERED n seconds
    assert sent[0] == "SENT" and int(sent[1]) == 200, out
    assert int(sent[3]) == int(sent[1]), out


def test_an_error_out_of_a_callback_does_not_end_the_spinning_thread(
        capsys: pytest.CaptureFixture[str]) -> None:
    """Under a flood of goals rclpy's action server raised out of spin_once ("Failed to expire
    goals") and ended the thread serving the stops; now it is reported once and spinning
    goes on."""
    pytest.importorskip("rclpy", reason=_why)
    import threading

    from articutool.ros2.cli import _spin

    class Executor:
        calls = 0

        def spin_once(self, timeout_sec: float) -> None:
            self.calls += 1
            if self.calls <= 3:
                raise RuntimeError("Failed to expire goals")
            stop.set()
    stop = threading.Event()
    ex = Executor()
    _spin(ex, stop)
    assert ex.calls == 4
    assert capsys.readouterr().err.count("Failed to expire goals") == 1
