"""``articutool view --recording FILE.mcap``: an MCAP recording replayed as an 8-joint motion.

An MCAP recording (``--record FILE.mcap`` of ``tool``, ``client``, ``meal``, ``experiment``)
holds ROS 2 messages, not the MuJoCo state: the viewer replays the wrist's joint states
(``/articutool/<id>/joint_states``) and, when recorded (the physics world), the arm's
(``/arm/joint_states``), on the model, with the plan view's tilt colouring. Without arm
joint states (a tool or client recording) the arm rests at ``Resting``. The food is not in an
MCAP recording: the ``.npz`` recording (``articutool sim/meal --record F.npz``) keeps the full
MuJoCo state for that.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from articutool.link import cdr
from articutool.sim.recording import RecordingError
from articutool.spec import Spec
from articutool.trajectory import JointTrajectory

__all__ = ["load_mcap_motion"]

_ARM_TOPIC = "/arm/joint_states"


def _series(stamps: list[float], rows: list[NDArray[np.float64]]
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    t = np.asarray(stamps, dtype=float)
    q = np.asarray(rows, dtype=float)
    keep = np.concatenate([[True], np.diff(t) > 0])  # strictly increasing times
    return t[keep], q[keep]


def load_mcap_motion(path: str | Path, spec: Spec, notes: list[str] | None = None
                     ) -> JointTrajectory:
    """The recorded motion as an 8-joint trajectory (arm 1..6, pitch, roll) from time 0.

    Read with :func:`articutool.link.recording.read_recording` (file order, every CRC
    checked), then ordered by log time here: a recording cut by a crash or ``kill -9`` is
    replayed up to its last complete chunk, and ``notes`` (when given) receives a line
    saying so. Raises :class:`RecordingError` naming the problem (not a readable MCAP file,
    corrupt, no wrist joint states).
    """
    from articutool.link.recording import RecordingError as McapReadError
    from articutool.link.recording import read_recording

    p = Path(path)
    wrist_names = tuple(spec.wrist.joint_names)
    arm_names = tuple(spec.arm.joint_names)
    try:
        rec = read_recording(p, topics=lambda t: t == _ARM_TOPIC or t.endswith("/joint_states"))
    except McapReadError as err:
        raise RecordingError(str(err)) from None
    if rec.cut and notes is not None:
        notes.append(rec.cut)
    wt: list[float] = []
    wq: list[NDArray[np.float64]] = []
    at: list[float] = []
    aq: list[NDArray[np.float64]] = []
    for msg in sorted(rec.messages, key=lambda x: x.log_time_ns):
        arm = msg.topic == _ARM_TOPIC
        try:
            js = cdr.decode(msg.data, cdr.JOINT_STATE)
        except cdr.LinkDecodeError:
            continue
        names = tuple(str(n) for n in js.name)
        want = arm_names if arm else wrist_names
        if set(names) != set(want) or len(js.position) != len(names):
            continue
        pos = dict(zip(names, np.asarray(js.position, dtype=float), strict=True))
        (at if arm else wt).append(msg.log_time_ns * 1e-9)
        (aq if arm else wq).append(np.array([pos[n] for n in want]))
    if len(wt) < 2:
        raise RecordingError(f"recording {p} holds fewer than two wrist joint states "
                             f"({'/'.join(wrist_names)}); nothing to replay")
    t, qw = _series(wt, wq)
    if len(at) >= 2:
        ta, qa = _series(at, aq)
        qa = np.stack([np.interp(t, ta, qa[:, j]) for j in range(qa.shape[1])], axis=1)
    else:
        qa = np.tile(np.asarray(spec.arm.configuration("Resting"), dtype=float), (t.size, 1))
    q = np.concatenate([qa, qw], axis=1)
    v = np.gradient(q, t, axis=0) if t.size > 1 else np.zeros_like(q)
    return JointTrajectory((*arm_names, *wrist_names), t - t[0], q, v)
