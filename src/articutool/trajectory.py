"""Joint trajectories in the shape of ``trajectory_msgs/JointTrajectory``.

One type serves the arm (6 joints), the wrist (2 joints, [pitch, roll]) and the 8-DOF arm.
JSON form (what ``articutool verify`` reads)::

    {"joint_names": ["j2n6s200_joint_1", ...],
     "points": [{"positions": [...], "velocities": [...], "time_from_start": 0.0}, ...]}

``time_from_start`` is seconds, or ``{"sec": int, "nanosec": int}`` as ROS writes it.
Between waypoints the trajectory is a cubic Hermite spline through positions and velocities,
as ``joint_trajectory_controller`` interpolates it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.datafile import read_document

__all__ = ["JointTrajectory", "TrajectoryError", "smooth_joint_motion"]


class TrajectoryError(ValueError):
    """A trajectory is malformed: wrong shapes, non-finite values, unordered times."""


def _time_value(t: Any, where: str) -> float:
    if isinstance(t, dict):
        try:
            sec, nsec = t["sec"], t.get("nanosec", 0)
        except (KeyError, TypeError):
            raise TrajectoryError(
                f"{where}.time_from_start must have 'sec' and 'nanosec'"
            ) from None
        if not isinstance(sec, int) or not isinstance(nsec, int) or not 0 <= nsec < 10**9:
            raise TrajectoryError(f"{where}.time_from_start: sec/nanosec must be integers, "
                                  "nanosec in [0, 1e9)")
        return sec + nsec * 1e-9
    if isinstance(t, bool) or not isinstance(t, int | float):
        raise TrajectoryError(f"{where}.time_from_start must be a number of seconds")
    return float(t)


@dataclass(frozen=True)
class JointTrajectory:
    """A time-parameterised joint trajectory: N waypoints of J joints."""

    joint_names: tuple[str, ...]
    times: NDArray[np.float64]  # (N,) seconds from start, strictly increasing
    positions: NDArray[np.float64]  # (N, J)
    velocities: NDArray[np.float64]  # (N, J)

    def __post_init__(self) -> None:
        names = tuple(self.joint_names)
        t = np.asarray(self.times, dtype=np.float64)
        q = np.asarray(self.positions, dtype=np.float64)
        v = np.asarray(self.velocities, dtype=np.float64)
        if len(names) == 0 or len(set(names)) != len(names):
            raise TrajectoryError("joint_names must be non-empty and unique")
        if t.ndim != 1 or t.size < 1:
            raise TrajectoryError(f"times must be a non-empty 1-D array; got shape {t.shape}")
        for label, a in (("positions", q), ("velocities", v)):
            if a.shape != (t.size, len(names)):
                raise TrajectoryError(
                    f"{label} must have shape ({t.size}, {len(names)}) = (points, joints); "
                    f"got {a.shape}"
                )
        for label, a in (("times", t), ("positions", q), ("velocities", v)):
            if not np.isfinite(a).all():
                i = int(np.argwhere(~np.isfinite(a))[0][0])
                raise TrajectoryError(f"{label} of point {i} is not finite (NaN or inf)")
        if t[0] < 0:
            raise TrajectoryError(f"time_from_start of point 0 must be >= 0; got {t[0]}")
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            i = int(bad[0]) + 1
            raise TrajectoryError(
                f"time_from_start must increase strictly: point {i} ({t[i]} s) "
                f"is not after point {i - 1} ({t[i - 1]} s)"
            )
        for a in (t, q, v):
            a.setflags(write=False)
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "positions", q)
        object.__setattr__(self, "velocities", v)

    @property
    def duration(self) -> float:
        """Time of the last waypoint (s)."""
        return float(self.times[-1])

    def __len__(self) -> int:
        return int(self.times.size)

    def reordered(self, joint_names: list[str] | tuple[str, ...]) -> JointTrajectory:
        """The same trajectory with columns in ``joint_names`` order (all must be present);
        this trajectory itself when they already are (it is immutable)."""
        if tuple(joint_names) == self.joint_names:
            return self
        missing = [n for n in joint_names if n not in self.joint_names]
        extra = [n for n in self.joint_names if n not in joint_names]
        if missing or extra:
            raise TrajectoryError(
                f"joint_names do not match: missing {missing}, unexpected {extra}; "
                f"expected {list(joint_names)}"
            )
        idx = [self.joint_names.index(n) for n in joint_names]
        return JointTrajectory(tuple(joint_names), self.times, self.positions[:, idx],
                               self.velocities[:, idx])

    def sample(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions and velocities at times ``t`` (clamped to the trajectory's span).

        Cubic Hermite interpolation between waypoints; returns arrays (..., J).
        """
        t = np.clip(np.asarray(t, dtype=np.float64), self.times[0], self.times[-1])
        if len(self) == 1:
            shape = t.shape + (len(self.joint_names),)
            return (np.broadcast_to(self.positions[0], shape).copy(),
                    np.broadcast_to(self.velocities[0], shape).copy())
        i = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self) - 2)
        t0, t1 = self.times[i], self.times[i + 1]
        h = (t1 - t0)[..., None]
        s = ((t - t0) / (t1 - t0))[..., None]
        p0, p1 = self.positions[i], self.positions[i + 1]
        m0, m1 = self.velocities[i] * h, self.velocities[i + 1] * h
        s2, s3 = s * s, s * s * s
        pos = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0
               + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1)
        vel = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0
               + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1) / h
        return pos, vel

    # ------------------------------------------------------------------ I/O --
    @classmethod
    def from_dict(cls, data: Any) -> JointTrajectory:
        """Build from the JSON/ROS shape described in the module docstring."""
        if not isinstance(data, dict):
            raise TrajectoryError("trajectory must be a JSON object with joint_names and points")
        names = data.get("joint_names")
        points = data.get("points")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise TrajectoryError("joint_names must be a list of strings")
        if not isinstance(points, list) or not points:
            raise TrajectoryError("points must be a non-empty list")
        times, pos, vel = [], [], []
        for i, p in enumerate(points):
            where = f"points[{i}]"
            if not isinstance(p, dict):
                raise TrajectoryError(f"{where} must be an object")
            for key in ("positions", "velocities", "time_from_start"):
                if key not in p:
                    raise TrajectoryError(f"{where} is missing '{key}'")
            times.append(_time_value(p["time_from_start"], where))
            for key, out in (("positions", pos), ("velocities", vel)):
                vals = p[key]
                if (not isinstance(vals, list) or len(vals) != len(names)
                        or not all(isinstance(x, int | float) and not isinstance(x, bool)
                                   for x in vals)):
                    raise TrajectoryError(
                        f"{where}.{key} must be a list of {len(names)} numbers"
                    )
                if not all(math.isfinite(x) for x in vals):
                    raise TrajectoryError(f"{where}.{key} must be finite (got NaN or inf)")
                out.append(vals)
        return cls(tuple(names), np.array(times), np.array(pos, dtype=float),
                   np.array(vel, dtype=float))

    def to_dict(self) -> dict[str, Any]:
        """The JSON/ROS shape (times in seconds)."""
        return {
            "joint_names": list(self.joint_names),
            "points": [
                {"positions": q.tolist(), "velocities": v.tolist(), "time_from_start": float(t)}
                for t, q, v in zip(self.times, self.positions, self.velocities, strict=True)
            ],
        }

    @classmethod
    def load(cls, path: str | Path) -> JointTrajectory:
        """Read a trajectory JSON file."""
        data = read_document(path, "trajectory file", TrajectoryError, fmt="json")
        try:
            return cls.from_dict(data)
        except TrajectoryError as err:  # say which file the field is in
            raise TrajectoryError(f"trajectory file {path}: {err}") from None

    def save(self, path: str | Path) -> None:
        """Write the trajectory as JSON (refuses to overwrite an existing file)."""
        p = Path(path)
        with p.open("x", encoding="utf-8") as f:
            json.dump(self.to_dict(), f, indent=1)


def smooth_joint_motion(q0: ArrayLike, q1: ArrayLike, max_velocity: ArrayLike,
                        joint_names: list[str] | tuple[str, ...], duration: float | None = None,
                        n: int = 41) -> JointTrajectory:
    """A rest-to-rest quintic joint motion q0 → q1, slow enough for ``max_velocity`` (the
    quintic's peak speed is 1.875 × the mean) unless ``duration`` is given."""
    a, b = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    vmax = np.asarray(max_velocity, dtype=float)
    need = float(np.max(1.875 * np.abs(b - a) / vmax)) if a.size else 0.0
    T = max(duration if duration is not None else need, need, 1e-3)
    s = np.linspace(0.0, 1.0, n)
    pos_s = 10 * s**3 - 15 * s**4 + 6 * s**5
    vel_s = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    return JointTrajectory(tuple(joint_names), s * T, a + np.outer(pos_s, b - a),
                           np.outer(vel_s, b - a))
