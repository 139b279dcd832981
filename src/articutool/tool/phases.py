"""The phases of a food primitive: the segments a primitive is planned as (thesis §4.4).

Each phase is stepped once per control tick with the primitive's elapsed time in the phase
and the measured joints, and returns ``(command (2,), fraction done 0..1, finished)``. Every
phase drives both joints: joints it does not move are held at ``target``. A phase reads three
things of its primitive (:class:`PhaseHost`): the position tolerance, the capped P command
toward a position error (``track``) and this tick's fresh F/T force (``force``).

Pure; :mod:`articutool.tool.primitive_base` plans primitives from these, and
:mod:`articutool.tool.primitives` is the library.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["TWO_PI", "Hold", "Move", "Phase", "PhaseHost", "Sweep", "Vibrate",
           "VibrateUntilStable", "Weigh"]

TWO_PI = 2.0 * math.pi


class PhaseHost(Protocol):
    """What a phase reads of the primitive that runs it."""

    tolerance: float
    force: NDArray[np.float64] | None

    def track(self, err: NDArray[np.float64], speed: NDArray[np.float64]
              ) -> NDArray[np.float64]: ...


class Phase:
    """One segment of a primitive. ``step`` → (command (2,), fraction done 0..1, finished).

    Every phase drives both joints: joints it does not move are held at ``target``.
    """

    def __init__(self, label: str, target: ArrayLike, speed: ArrayLike, nominal: float) -> None:
        self.label = label
        self.target = np.array(target, dtype=np.float64)
        self.speed = np.array(speed, dtype=np.float64)
        self.nominal = float(nominal)

    def step(
        self, prim: PhaseHost, t: float, q: NDArray[np.float64], dt: float
    ) -> tuple[NDArray[np.float64], float, bool]:
        raise NotImplementedError


class Move(Phase):
    """Both joints to ``target`` (P on the measured error, capped at ``speed``)."""

    def __init__(
        self, label: str, start: ArrayLike, target: ArrayLike, speed: ArrayLike, gain: float
    ) -> None:
        dist = np.abs(np.asarray(target, float) - np.asarray(start, float))
        super().__init__(label, target, speed, float(np.max(dist / speed)) + 3.0 / gain)
        self._dist: NDArray[np.float64] | None = None

    def step(self, prim, t, q, dt):
        err = self.target - q
        if self._dist is None:
            self._dist = np.abs(err)
        if (np.abs(err) <= prim.tolerance).all():
            return np.zeros(2), 1.0, True
        moving = self._dist > prim.tolerance  # held joints do not count towards progress
        frac = 0.0
        if moving.any():
            frac = float(np.clip(1.0 - np.max(np.abs(err[moving]) / self._dist[moving]), 0, 1))
        return prim.track(err, self.speed), frac, False


class Sweep(Phase):
    """Joint ``joint`` at a constant ``speed`` from ``start`` towards and past ``target`` (a
    flick: no slowing down before it), ending once the measured joint has reached it; the
    other joint held at ``target``."""

    def __init__(self, label: str, start: ArrayLike, target: ArrayLike, speed: ArrayLike,
                 joint: int) -> None:
        start, target = np.asarray(start, float), np.asarray(target, float)
        self.joint = int(joint)
        dist = abs(float(target[self.joint] - start[self.joint]))
        super().__init__(label, target, speed, dist / float(np.asarray(speed)[self.joint]))
        self.direction = math.copysign(1.0, float(target[self.joint] - start[self.joint]))
        self._dist = dist

    def step(self, prim, t, q, dt):
        j = self.joint
        left = self.direction * (self.target[j] - q[j])
        if left <= 0.0:
            return np.zeros(2), 1.0, True
        cmd = prim.track(self.target - q, self.speed)
        cmd[j] = self.direction * self.speed[j]
        return cmd, float(np.clip(1.0 - left / max(self._dist, 1e-12), 0.0, 1.0)), False


class Hold(Phase):
    """Hold ``target`` for ``duration`` seconds."""

    def __init__(self, label: str, target: ArrayLike, speed: ArrayLike, duration: float) -> None:
        super().__init__(label, target, speed, duration)
        self.duration = float(duration)

    def step(self, prim, t, q, dt):
        if t >= self.duration:
            return np.zeros(2), 1.0, True
        return prim.track(self.target - q, self.speed), t / self.duration, False


class Vibrate(Phase):
    """Roll ``target[1] + A·sin(2πft)`` for ``duration`` s; pitch held at ``target[0]``."""

    def __init__(
        self,
        label: str,
        target: ArrayLike,
        speed: ArrayLike,
        frequency: float,
        amplitude: float,
        duration: float,
    ) -> None:
        super().__init__(label, target, speed, duration)
        self.w = TWO_PI * float(frequency)
        self.amplitude = float(amplitude)
        self.duration = float(duration)

    def step(self, prim, t, q, dt):
        if t >= self.duration:
            return np.zeros(2), 1.0, True
        cmd = prim.track(self.target - q, self.speed)
        t1 = min(t + dt, self.duration)
        # Exact increment of A·sin(ωt) over the tick: the tick average of A·ω·cos(ωt).
        cmd[1] = self.amplitude * (math.sin(self.w * t1) - math.sin(self.w * t)) / dt
        return cmd, t / self.duration, False


# Thesis §7.1.2 names "closed-loop, sensor-driven primitives" as future work. These read the
# wrist's F/T sensor through :meth:`Primitive.sense` (the runtime passes each tick's fresh
# tared force, or None) and weigh the load as |mean tared force| / g over whole windows.
# The tare is taken with the utensil empty and level, so a weight is only compared at the
# start orientation (VIBRATE: windows of whole vibration periods about it; TILT: weighed
# after returning to it); a tick without a fresh sample adds nothing. Both are bounded.
class _Weighing:
    """Tared force samples over one window → the load in grams (None: no sample)."""

    def __init__(self, gravity: float) -> None:
        self.g = gravity
        self.samples: list[NDArray[np.float64]] = []

    def add(self, force: NDArray[np.float64] | None) -> None:
        if force is not None:
            self.samples.append(force)

    def grams(self) -> float | None:
        if not self.samples:
            return None
        m = float(np.linalg.norm(np.mean(self.samples, axis=0))) / self.g * 1000.0
        self.samples = []
        return m


class VibrateUntilStable(Vibrate):
    """Vibrate like :class:`Vibrate`, ending early once two consecutive windows weigh
    within ``stable_g`` of each other (the load stopped changing)."""

    def __init__(self, label, target, speed, frequency, amplitude, duration, window, stable_g,
                 gravity):
        super().__init__(label, target, speed, frequency, amplitude, duration)
        self.window, self.stable_g = float(window), float(stable_g)
        self.scale = _Weighing(gravity)
        self.weights: list[float] = []
        self._next = self.window
        self.settled = False

    def step(self, prim, t, q, dt):
        self.scale.add(prim.force)
        if t >= self._next - 1e-9:
            self._next += self.window
            m = self.scale.grams()
            if m is not None:
                self.weights.append(m)
            if len(self.weights) >= 2 and abs(self.weights[-1] - self.weights[-2]) <= self.stable_g:
                self.settled = True
                return np.zeros(2), 1.0, True
        return super().step(prim, t, q, dt)


class Weigh(Hold):
    """Hold still for ``duration`` s and weigh; ``stop_all`` when the load ≤ ``target_g``."""

    def __init__(self, label, target, speed, duration, target_g, gravity):
        super().__init__(label, target, speed, duration)
        self.target_g = float(target_g)
        self.scale = _Weighing(gravity)
        self.grams: float | None = None
        self.stop_all = self.finished = False

    def step(self, prim, t, q, dt):
        self.scale.add(prim.force)
        cmd, frac, finished = super().step(prim, t, q, dt)
        if finished:
            self.finished = True
            self.grams = self.scale.grams()
            self.stop_all = self.grams is not None and self.grams <= self.target_g
        return cmd, frac, finished
