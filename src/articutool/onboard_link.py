"""The link process of ``articutool tool``: the Zenoh link and its server, beside the loop.

``articutool tool`` (``onboard.py``) runs the 50 Hz loop in its own process and starts this
one for the network: the Zenoh session (``ZenohTransport``), the optional MCAP recorder and the
link server (``ToolServer``), which serves a :class:`~articutool.tool.channel.LoopProxy` of
the loop. Every message from the network — verified, refused, decoded, validated — costs this
process's CPU and interpreter lock, never the loop's. The two talk over a socket pair
(``tool/channel.py``).

Lifetime: the loop process starts this one first (:class:`LinkProcess`), sends it the link
config, the spec and the recording path, and waits until the session is open (or the reason
it cannot be: exit 2 before anything moves); once the drivers are open it sends the first
state and waits until the endpoints are declared; then the loop starts. This process
ignores SIGINT and SIGTERM: it ends when the loop process closes the channel — after the
motors stopped and the drivers closed — or ends itself, so the link is always closed last.
If it ends first (a crash, an out-of-memory kill), the loop process stops the motors and
exits 1: a tool that cannot hear a stop does not go on moving.

Priority: when the loop could not have real-time priority, this process runs at nice 10 so
that the scheduler still favours the loop (``onboard.py``).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import articutool
from articutool.spec import Spec
from articutool.tool.channel import (
    ChannelClosedError,
    FrameReader,
    LoopChannel,
    LoopProxy,
    send_frame,
)

__all__ = ["LinkProcess", "LinkProcessError", "main"]

_OPEN_S = 60.0  # s for the link process to import, open the session and say so
_SERVE_S = 30.0  # s for it to declare the endpoints once the loop's first state came
_EXIT_S = 15.0  # s for it to close the session and end after the channel closed
_SWITCH_S = 0.001  # s, the interpreter's switch interval here (stops wait less behind floods)


class LinkProcessError(RuntimeError):
    """The link process could not open the link or serve it (the message says why)."""


class LinkProcess:
    """The link process, seen from the loop process (module doc).

    Starting it opens the link (``LinkProcessError`` with the reason if it cannot);
    :meth:`attach` hands it the runtime's first state and returns the loop's end of the
    channel once the endpoints are declared; :meth:`close` closes the channel and waits
    until the process ended.
    """

    def __init__(self, cfg: Any, spec: Spec, record: Path | None = None, *,
                 nice: int = 0) -> None:
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock = ours
        self.reader = FrameReader(ours)
        src = str(Path(articutool.__file__).resolve().parents[1])  # the same code as ours
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (src, env.get("PYTHONPATH")) if p)
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "articutool.onboard_link", str(theirs.fileno()),
                 str(int(nice))], pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
                env=env)
        finally:
            theirs.close()
        try:
            send_frame(ours, ("init", cfg, spec, None if record is None else str(record)))
            self._expect("opened", _OPEN_S)
        except BaseException:
            self.close()
            raise

    @property
    def pid(self) -> int:
        """The link process's id."""
        return self.proc.pid

    def _expect(self, what: str, timeout: float) -> None:
        try:
            msg = self.reader.read(timeout)
        except (TimeoutError, ChannelClosedError) as err:
            raise LinkProcessError(f"the link process did not start ({err}; exit code "
                                   f"{self.proc.poll()})") from None
        if isinstance(msg, tuple) and msg and msg[0] == "error":
            raise LinkProcessError(str(msg[1]))
        if msg != (what,):
            raise LinkProcessError(f"the link process said {str(msg)[:80]!r}, not {what!r}")

    def attach(self, runtime: Any, *, extra: dict[str, float] | None = None,
               on_lost: Callable[[str], None] | None = None) -> LoopChannel:
        """Send ``runtime``'s first state, wait until the endpoints are declared, and hook
        the channel into the runtime's loop (``set_link_work``)."""
        channel = LoopChannel(self.reader, runtime, extra=extra, on_lost=on_lost)
        send_frame(self.sock, channel.report())
        self._expect("serving", _SERVE_S)
        channel.start()
        runtime.set_link_work(channel.work_once)
        return channel

    def close(self) -> int | None:
        """Close the channel and wait for the process to end (killed after ``_EXIT_S``);
        its exit code."""
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()
        proc = getattr(self, "proc", None)
        if proc is None:
            return None
        try:
            return proc.wait(timeout=_EXIT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            return proc.wait()


def _open(cfg: Any, record: str | None) -> tuple[Any, Any]:
    """The transport (recording if ``record``) and the recorder; LinkProcessError."""
    from articutool.link.config import ConfigError
    from articutool.link.transport import LinkOpenError
    from articutool.link.zenoh_transport import ZenohTransport

    try:
        link: Any = ZenohTransport(cfg, "tool")
    except ConfigError as err:
        raise LinkProcessError(str(err)) from None
    except LinkOpenError as err:
        raise LinkProcessError(f"cannot serve the link: {err} (is another articutool tool "
                               "running on that endpoint?)") from None
    recorder = None
    if record is not None:
        from articutool.link.recording import McapRecorder, RecordingError, RecordingTransport

        try:
            recorder = McapRecorder(record)
        except RecordingError as err:
            link.close()
            raise LinkProcessError(f"--record: {err}") from None
        link = RecordingTransport(link, recorder)
    return link, recorder


def main(argv: Sequence[str] | None = None) -> int:
    """The link process: ``python -m articutool.onboard_link FD NICE``."""
    args = list(sys.argv[1:] if argv is None else argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the loop process decides when to stop
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if int(args[1]):
        os.nice(int(args[1]))
    sock = socket.socket(fileno=int(args[0]))
    reader = FrameReader(sock)
    try:
        _, cfg, spec, record = reader.read()  # type: ignore[misc]
    except ChannelClosedError:
        return 0
    sys.setswitchinterval(_SWITCH_S)
    try:
        link, recorder = _open(cfg, record)
    except LinkProcessError as err:
        send_frame(sock, ("error", str(err)))
        return 0
    from articutool.link.server import ToolServer

    server = None
    proxy = LoopProxy(reader, spec)
    try:
        send_frame(sock, ("opened",))
        proxy.first_report.wait()
        if proxy.closed.is_set():
            return 0
        server = ToolServer(proxy, link, cfg, rate_hz=cfg.publish_rate_hz
                            or spec.wrist.loop_rate_hz)
        try:
            server.start()
        except Exception as err:
            server = None
            proxy.send(("error", f"cannot serve the link: {type(err).__name__}: {err}"))
            return 0
        proxy.send(("serving",))
        proxy.closed.wait()
    except OSError:  # the loop process is gone
        pass
    finally:
        if server is not None:
            server.stop()
        link.close()
        if recorder is not None:
            recorder.close()
            print(f"recording: {record} ({recorder.count} messages)", file=sys.stderr)
        proxy.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
