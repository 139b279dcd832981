"""TRAJECTORY mode: validating and following a wrist trajectory (thesis §4.2, §4.4).

The runtime follows a wrist :class:`~articutool.trajectory.JointTrajectory` (e.g. the
verifier's synchronised leveling trajectory) with ``q̇ = q̇_ref(t) + K (q_ref(t) − q)``,
``K = spec.primitives.position_gain``, then holds the last point until the mode changes. A
``start_delay`` (a ``header.stamp`` in the future, synchronised with the arm) holds the present
position until then, as ROS trajectory controllers do.

A trajectory is refused with a reason (:class:`~articutool.trajectory.TrajectoryError`) when
its joints are not the wrist's, its last point is later than ``spec.primitives.max_duration_s``
(120 s) after its start, a waypoint or the interpolated spline leaves ``spec.wrist`` limits or
exceeds ``spec.wrist.max_velocity``, or a first point at t = 0 is farther than one tick's
travel from the present joints.

The spline is checked at four samples per tick over the whole trajectory, so the length bound
also bounds that check (at most 24 001 samples, about 1 MB, before any is taken): a wrist
trajectory is a bounded motion like a primitive, which ends on its own if the PC is gone, and a
span sent in the wrong unit (nanoseconds as seconds: 1e9 s) is refused with a message instead
of asking for terabytes. :class:`~articutool.tool.runtime.ToolRuntime` composes
a :class:`TrajectoryFollower`; it holds no lock of its own (the runtime's serialises it).
"""

from __future__ import annotations

import math
import weakref

import numpy as np
from numpy.typing import NDArray

from articutool.spec import Spec
from articutool.trajectory import JointTrajectory, TrajectoryError

__all__ = ["TrajectoryFollower"]


class TrajectoryFollower:
    """The trajectory being followed, its clock, and the checks it passed."""

    def __init__(self, spec: Spec) -> None:
        w = spec.wrist
        self.joint_names: tuple[str, str] = (w.joint_names[0], w.joint_names[1])
        self.period = w.period
        self._vmax = w.velocity_limits
        self._limits = w.limits
        self._gain = spec.primitives.position_gain
        self.max_duration = spec.primitives.max_duration_s
        # samples of the densest spline check (4 per tick over max_duration), plus the ends
        self._max_samples = math.ceil(self.max_duration / (self.period / 4)) + 2
        # Trajectories prevalidate returned, by id while they live (the dataclass holds
        # arrays, so it cannot be hashed into a WeakSet).
        self._prechecked: dict[int, weakref.ref[JointTrajectory]] = {}
        self.trajectory: JointTrajectory | None = None
        self._t0: float | None = None
        self._hold = np.zeros(2)
        self.progress = math.nan  # percent of the duration elapsed
        self.error = math.nan  # max |q_ref − q| at the last command (rad)

    # -- following --
    def start(self, traj: JointTrajectory, t0: float | None) -> None:
        """Follow ``traj`` (validated) from time ``t0`` (None: the next command's time)."""
        self.trajectory = traj
        self._t0 = t0
        self._hold = traj.positions[0].copy()  # where the wrist is (see validation)
        self.progress = 0.0

    def drop(self) -> None:
        """Forget the trajectory (leaving TRAJECTORY)."""
        self.trajectory = None
        self._t0 = None

    def command(self, q: NDArray[np.float64], now: float) -> NDArray[np.float64]:
        """The joint velocity command at ``now`` for the present joints ``q``."""
        traj = self.trajectory
        assert traj is not None
        if self._t0 is None:
            self._t0 = now
        t = now - self._t0
        if t < 0.0:  # not started yet (start_delay): hold where the wrist was
            pos, vel = self._hold, np.zeros(2)
        else:
            pos, vel = traj.sample(t)
        if t >= traj.duration:
            vel = np.zeros(2)  # hold the last point
        self.progress = (100.0 * min(1.0, max(t, 0.0) / traj.duration)
                         if traj.duration > 0 else 100.0)
        err = pos - q
        self.error = float(np.abs(err).max())
        return vel + self._gain * err

    # -- validation --
    def prevalidate(self, trajectory: JointTrajectory) -> JointTrajectory:
        """The checks that do not depend on the wrist's state; see
        :meth:`~articutool.tool.runtime.ToolRuntime.prevalidate_trajectory`."""
        return self.adopt(self._checked_shape_and_limits(trajectory))

    def adopt(self, traj: JointTrajectory) -> JointTrajectory:
        """Remember ``traj`` as prevalidated (while it lives): :meth:`validated` then only
        checks its start."""
        key = id(traj)
        self._prechecked[key] = weakref.ref(traj, lambda _r: self._prechecked.pop(key, None))
        return traj

    def is_prechecked(self, traj: JointTrajectory) -> bool:
        """Whether :meth:`prevalidate` returned ``traj`` (or it was adopted)."""
        ref = self._prechecked.get(id(traj))
        return ref is not None and ref() is traj

    def validated(
        self, trajectory: JointTrajectory, q_now: NDArray[np.float64]
    ) -> JointTrajectory:
        """``trajectory`` in the wrist's joint order, starting from ``q_now``: a first point
        after t = 0 gets the present joints prepended. Raises TrajectoryError, TypeError."""
        if self.is_prechecked(trajectory):  # names, limits checked in the link thread
            traj = trajectory
        else:
            traj = self._checked_shape_and_limits(trajectory)
        names, vmax = list(self.joint_names), self._vmax
        if traj.times[0] > 0.0:
            # Start from where the wrist is: the spline moves it to the first point in time.
            # Hermite segments are local, so only the new first segment needs checking.
            traj = JointTrajectory(
                traj.joint_names, np.concatenate([[0.0], traj.times]),
                np.vstack([q_now, traj.positions]), np.vstack([np.zeros(2), traj.velocities]))
            self._check_spline(traj, 0.0, float(traj.times[1]))
        else:
            gap = np.abs(traj.positions[0] - q_now)
            reach = vmax * self.period
            j = int(np.argmax(gap / reach))
            if gap[j] > reach[j]:
                raise TrajectoryError(
                    f"the first point (t = 0) is {gap[j]:.4f} rad from the present {names[j]} "
                    f"({q_now[j]:.4f} rad), more than one tick's travel ({reach[j]:.4f} rad); "
                    "give the first point a time_from_start > 0 to move there")
        return traj

    def _check_limits(self, t: NDArray, pos: NDArray, vel: NDArray, what: str) -> None:
        names, lim, vmax = list(self.joint_names), self._limits, self._vmax
        for j, name in enumerate(names):
            lo, hi = lim[j]
            bad = np.flatnonzero((pos[:, j] < lo - 1e-9) | (pos[:, j] > hi + 1e-9))
            if bad.size:
                k = int(bad[0])
                raise TrajectoryError(
                    f"{what} at t = {t[k]:.3f} s: {name} = {pos[k, j]:.4f} rad is outside "
                    f"[{lo:.4f}, {hi:.4f}] rad (spec.wrist limits)")
            bad = np.flatnonzero(np.abs(vel[:, j]) > vmax[j] * (1 + 1e-9))
            if bad.size:
                k = int(bad[0])
                raise TrajectoryError(
                    f"{what} at t = {t[k]:.3f} s: {name} velocity {vel[k, j]:.4f} rad/s is "
                    f"outside [{-vmax[j]:g}, {vmax[j]:g}] rad/s (spec.wrist.max_velocity)")

    def _check_spline(self, traj: JointTrajectory, t0: float, t1: float) -> None:
        """The spline between waypoints can overshoot; check it densely on [t0, t1] (4
        samples per tick, and every waypoint in the span)."""
        n = max(2, math.ceil((t1 - t0) / (self.period / 4)) + 1)
        if n > self._max_samples:  # unreachable past _check_duration; never sample unbounded
            raise TrajectoryError(f"{t1 - t0:g} s of spline to check: longer than "
                                  f"{self.max_duration:g} s (spec.primitives.max_duration_s)")
        inside = traj.times[(traj.times >= t0) & (traj.times <= t1)]
        ts = np.unique(np.concatenate([np.linspace(t0, t1, n), inside]))
        pos, vel = traj.sample(ts)
        self._check_limits(ts, pos, vel, "interpolated trajectory")

    def _checked_shape_and_limits(self, trajectory: JointTrajectory) -> JointTrajectory:
        if not isinstance(trajectory, JointTrajectory):
            raise TypeError(f"expected a JointTrajectory; got {type(trajectory).__name__}")
        names = list(self.joint_names)
        if sorted(trajectory.joint_names) != sorted(names):
            raise TrajectoryError(f"joint_names must be the wrist's {names}; "
                                  f"got {list(trajectory.joint_names)}")
        end = float(trajectory.times[-1])
        if end > self.max_duration:
            raise TrajectoryError(
                f"the last point's time_from_start is {end:g} s; a wrist trajectory ends at most "
                f"{self.max_duration:g} s after its start (spec.primitives.max_duration_s): "
                "split a longer motion, and send time_from_start in seconds")
        traj = trajectory.reordered(names)
        self._check_limits(traj.times, traj.positions, traj.velocities, "waypoint")
        self._check_spline(traj, float(traj.times[0]), float(traj.times[-1]))
        return traj
