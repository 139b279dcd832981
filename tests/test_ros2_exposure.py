"""Who can reach ``articutool ros2``: the discovery check (pure) and the node refusing to
start, as a real process, unless discovery stays on the host or its own flag opens it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from articutool.ros2.exposure import ALLOW_FLAG, discovery_scope
from conftest import ros_domain_id

SRC = Path(__file__).resolve().parent.parent / "src"


@pytest.mark.parametrize(("env", "host_only", "says"), [
    ({}, False, "not set"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, False, "'SUBNET'"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"}, False, "SYSTEM_DEFAULT"),
    ({"ROS_LOCALHOST_ONLY": "1"}, False, "ROS_LOCALHOST_ONLY=1 is not read"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, True, "LOCALHOST"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": " localhost "}, True, "LOCALHOST"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}, True, "OFF"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "127.0.0.1;::1"},
     True, "LOCALHOST"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "localhost"},
     True, "LOCALHOST"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "127.0.0.1;pi.local"},
     False, "pi.local"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "192.0.2.7"},
     False, "192.0.2.7"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF", "ROS_STATIC_PEERS": "192.0.2.7"},
     True, "OFF"),  # rcl ignores static peers when discovery is off
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
      "FASTDDS_DEFAULT_PROFILES_FILE": "/etc/dds.xml"}, False, "FASTDDS_DEFAULT_PROFILES_FILE"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DISCOVERY_SERVER": "10.0.0.1:11811"},
     False, "ROS_DISCOVERY_SERVER"),
])
def test_discovery_scope(env: dict[str, str], host_only: bool, says: str) -> None:
    scope = discovery_scope(env)
    assert scope.host_only is host_only
    assert says in scope.why


def _ros2(env: dict[str, str], *args: str) -> subprocess.Popen[str]:
    full = {k: v for k, v in os.environ.items()
            if not k.startswith(("ROS_", "FASTDDS_", "FASTRTPS_"))}
    full.update(env, PYTHONPATH=str(SRC),
                ROS_DOMAIN_ID=str(ros_domain_id(salt=2)))
    return subprocess.Popen([sys.executable, "-m", "articutool", "ros2", *args], env=full,
                            text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


@pytest.mark.parametrize("env", [{}, {"ROS_LOCALHOST_ONLY": "1"},
                                 {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}],
                         ids=["default", "localhost_only_var", "subnet"])
def test_the_node_refuses_an_open_graph_without_its_flag(env: dict[str, str]) -> None:
    p = _ros2(env, "--connect", "tcp/127.0.0.1:9", "--wait", "1")
    out, err = p.communicate(timeout=60)
    assert p.returncode == 2, (out, err)
    assert "refusing to serve the wrist to the network" in err and ALLOW_FLAG in err
    assert "Traceback" not in err and "serving" not in out


def test_the_flag_opens_it_and_says_so(tmp_path: Path) -> None:
    """With the flag the node starts and warns. The graph here is still local (LOCALHOST plus
    a harmless profile file the check cannot vouch for), so no traffic leaves the host."""
    pytest.importorskip("rclpy", reason="rclpy (CPython 3.11 on x86_64 only)")
    pytest.importorskip("articutool_interfaces.srv", reason="the built articutool_interfaces")
    profile = tmp_path / "dds.xml"
    profile.write_text('<?xml version="1.0"?>\n<dds xmlns="http://www.eprosima.com"/>\n')
    env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "FASTDDS_DEFAULT_PROFILES_FILE": str(profile)}
    refused = _ros2(env, "--verify-only")
    _, err = refused.communicate(timeout=60)
    assert refused.returncode == 2 and "FASTDDS_DEFAULT_PROFILES_FILE" in err
    p = _ros2(env, "--verify-only", ALLOW_FLAG)
    try:
        assert p.stdout is not None
        line = p.stdout.readline()
        assert "serving" in line, (line, p.stderr.read() if p.stderr else "")
    finally:
        p.send_signal(2)
        _, err = p.communicate(timeout=30)
    assert p.returncode == 0, err
    assert f"warning: {ALLOW_FLAG}" in err
