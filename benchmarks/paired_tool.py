"""Shared by the link benchmarks: a free loopback port, a process's resident memory, and the
real tool (``articutool tool`` on the simulated drivers) started as its own process, paired
with one PC (``articutool pair``) and listening on loopback TLS."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from articutool.link.config import LinkConfig, load_config
from articutool.link.pairing import pair

__all__ = ["ROOT", "PairedTool", "free_port", "rss_mb", "start_paired_tool"]

ROOT = Path(__file__).resolve().parent.parent


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rss_mb(pid: int) -> float:
    """Resident set size of ``pid`` in MB (Linux); NaN once the process is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


@dataclass
class PairedTool:
    """The tool process, the pairing folder and the PC's link config to reach it."""

    proc: subprocess.Popen[bytes]
    folder: Path
    pc_config: LinkConfig
    tool_config: Path


def start_paired_tool(prefix: str, *, extra_tool_config: str = "",
                      plain_port: int | None = None, duration_s: float | None = None,
                      pcs: tuple[str, ...] = ("pc-1",)) -> PairedTool:
    """Pair a tool with ``pcs`` in a new temporary folder and start ``articutool tool
    --no-level`` listening on loopback TLS (and plain TCP on ``plain_port``, to test that it
    refuses commands there); the config returned is the first PC's. ``extra_tool_config``
    is appended to the tool's link.toml."""
    folder = Path(tempfile.mkdtemp(prefix=prefix))
    pair(folder, "wrist-1", list(pcs))
    tool_cfg = folder / "wrist-1" / "link.toml"
    if extra_tool_config:
        tool_cfg.write_text(tool_cfg.read_text() + extra_tool_config)
    tls = free_port()
    cmd = [sys.executable, "-m", "articutool", "tool", "--no-level", "--link-config",
           str(tool_cfg), "--listen", f"tls/127.0.0.1:{tls}"]
    if plain_port is not None:
        cmd += ["--listen", f"tcp/127.0.0.1:{plain_port}"]
    if duration_s is not None:
        cmd += ["--duration", str(duration_s)]
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL,
                            env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    cfg = load_config(folder / pcs[0] / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{tls}",), listen=())
    return PairedTool(proc, folder, cfg, tool_cfg)
