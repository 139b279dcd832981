"""The food primitive's base class: parameters checked, phases planned, stepped with the safety
clip, progress and result reported (thesis §4.4; docs/hardware.md §6). The conventions, limits
and the library are described in :mod:`articutool.tool.primitives`, which re-exports
:class:`Primitive` and :class:`PrimitiveError`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.spec import Spec
from articutool.tool.api import PrimitiveStatus
from articutool.tool.kinematics import wrap_angle
from articutool.tool.phases import TWO_PI, Move, Phase

__all__ = ["Primitive", "PrimitiveError"]

_EPS_WEIGHT = 1e-3  # s: keeps zero-length phases in the progress weighting


class PrimitiveError(ValueError):
    """A primitive request was refused (unknown name, bad parameters, beyond a limit)."""


class Primitive:
    """A parameterised, stateful wrist motion (thesis §4.4). Build with :func:`make_primitive`.

    Subclasses set ``name`` and ``parameter_names`` and implement :meth:`_plan`.
    """

    name: ClassVar[str] = ""
    parameter_names: ClassVar[tuple[str, ...]] = ()
    #: Reads the F/T sensor (:meth:`sense`): refused by a runtime without one.
    needs_ft: ClassVar[bool] = False
    #: This tick's fresh tared force (N, sensor frame), or None (see :meth:`sense`).
    force: NDArray[np.float64] | None = None

    def __init__(self, params: Sequence[float], spec: Spec, q_start: ArrayLike) -> None:
        values = self._parse(params)
        w, p = spec.wrist, spec.primitives
        self.spec = spec
        self.vmax = w.velocity_limits
        self.gain = p.position_gain
        self.tolerance = p.position_tolerance
        self.roll_bound = w.roll_turn_budget * TWO_PI
        self._lo = np.array([w.pitch_limits[0], -self.roll_bound])
        self._hi = np.array([w.pitch_limits[1], self.roll_bound])
        q0 = np.asarray(q_start, dtype=np.float64)
        if q0.shape != (2,) or not np.isfinite(q0).all():
            raise PrimitiveError(
                f"q_start must be two finite joint angles [pitch, roll]; got {q_start!r}"
            )
        self.q_start = q0.copy()
        self.params = values
        self.phases: list[Phase] = self._plan(*values)
        nominal = sum(ph.nominal for ph in self.phases)
        if nominal > p.max_duration_s:
            speeds = [f"'{n}'" for n in self.parameter_names if "speed" in n or "velocity" in n]
            raise PrimitiveError(
                f"{self.name}: these parameters make a {nominal:.3g} s motion, above the "
                f"maximum {p.max_duration_s:g} s (spec.primitives.max_duration_s)"
                + (f"; raise {' or '.join(speeds)}" if speeds else "")
            )
        self.timeout = p.timeout_factor * nominal + p.timeout_margin_s
        w8 = np.array([ph.nominal + _EPS_WEIGHT for ph in self.phases])
        self._cum = np.concatenate([[0.0], np.cumsum(w8)]) / w8.sum()
        # Running state.
        self._q_raw = q0.copy()  # last measured joints, as measured
        self._q = q0.copy()  # same, with roll unwrapped tick by tick
        self._index = 0
        self._t_phase = 0.0
        self.elapsed = 0.0
        self._percent = 0.0
        self._done = False
        self._success = False
        self._message = ""

    # -- parameters ------------------------------------------------------------
    @classmethod
    def _parse(cls, params: Sequence[float]) -> tuple[float, ...]:
        names = cls.parameter_names
        try:
            values = [float(v) for v in params]
        except (TypeError, ValueError):
            raise PrimitiveError(
                f"{cls.name}: parameters must be numbers {list(names)}; got {params!r}"
            ) from None
        if len(values) != len(names):
            raise PrimitiveError(
                f"{cls.name} takes {len(names)} parameter(s) {list(names)}; got {len(values)}"
            )
        for n, v in zip(names, values, strict=True):
            if not math.isfinite(v):
                raise PrimitiveError(f"{cls.name}: parameter '{n}' must be finite; got {v}")
        return tuple(values)

    def _require(
        self,
        pname: str,
        v: float,
        lo: float,
        hi: float,
        *,
        lo_open: bool = False,
        hi_open: bool = False,
        unit: str = "",
        why: str = "",
    ) -> float:
        """Refuse ``v`` outside the interval, naming the parameter and the range."""
        ok = (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
        if not ok:
            if math.isinf(hi):
                rng = f"{'>' if lo_open else '≥'} {lo:g}"
            else:
                rng = f"in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
            note = f" ({why})" if why else ""
            raise PrimitiveError(
                f"{self.name}: parameter '{pname}' must be {rng}{' ' + unit if unit else ''}"
                f"{note}; got {v:g}"
            )
        return v

    def _speed(self, pname: str, v: float, joint: int) -> float:
        j = ("pitch", "roll")[joint]
        return self._require(
            pname,
            v,
            0.0,
            float(self.vmax[joint]),
            lo_open=True,
            unit="rad/s",
            why=f"{j} speed limit, spec.wrist.max_velocity",
        )

    def _max_duration(self, pname: str, v: float, key: str) -> float:
        """A duration in [0, spec.primitives.<key>] s: every primitive ends."""
        limit = getattr(self.spec.primitives, key)
        return self._require(pname, v, 0.0, limit, unit="s", why=f"spec.primitives.{key}")

    def _roll_in_budget(self, pname: str, roll_end: float, hint: str = "") -> None:
        if abs(roll_end) > self.roll_bound + 1e-12:
            b = self.spec.wrist.roll_turn_budget
            raise PrimitiveError(
                f"{self.name}: parameter '{pname}' would take the roll to "
                f"{roll_end / TWO_PI:+.2f} turns from the current net "
                f"{self.q_start[1] / TWO_PI:+.2f} turns, beyond the cable budget of "
                f"±{b:g} turns (spec.wrist.roll_turn_budget){hint}"
            )

    def _plan(self, *values: float) -> list[Phase]:
        """Validate the parameters (raise :class:`PrimitiveError`) and return the phases."""
        raise NotImplementedError

    # -- helpers for phases ----------------------------------------------------
    def track(self, err: NDArray[np.float64], speed: NDArray[np.float64]) -> NDArray[np.float64]:
        """P command toward a position error, capped per joint at ``speed``."""
        return np.clip(self.gain * err, -speed, speed)

    def move(self, label: str, start: ArrayLike, target: ArrayLike, speed: ArrayLike) -> Move:
        return Move(label, start, target, np.broadcast_to(speed, (2,)), self.gain)

    # -- running ---------------------------------------------------------------
    def sense(self, force: ArrayLike | None) -> None:
        """This tick's fresh tared F/T force (N), or None when no new valid sample came;
        call before :meth:`step`. Only closed-loop primitives (``needs_ft``) use it."""
        f = None if force is None else np.asarray(force, dtype=np.float64)
        self.force = f if f is not None and f.shape == (3,) and np.isfinite(f).all() else None

    def step(self, q_measured: ArrayLike, dt: float) -> NDArray[np.float64]:
        """One tick: the joint velocity command (rad/s) for the measured joints ``q``.

        Non-finite joints or ``dt <= 0`` raise ``ValueError`` (state unchanged); once done
        (finished, failed or cancelled) the command is zero.
        """
        q = np.asarray(q_measured, dtype=np.float64)
        if q.shape != (2,) or not np.isfinite(q).all():
            raise ValueError(f"q_measured must be two finite joint angles; got {q_measured!r}")
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0 s; got {dt}")
        if self._done:
            self._q_raw = q.copy()
            return np.zeros(2)
        d_roll = float(wrap_angle(q[1] - self._q_raw[1]))
        self._q = np.array([q[0], self._q[1] + d_roll])
        self._q_raw = q.copy()
        if self.elapsed > self.timeout:
            ph = self.phases[self._index]
            self._finish(
                False,
                f"timed out after {self.elapsed:.1f} s in phase '{ph.label}' "
                f"(a joint did not reach its target)",
            )
            return np.zeros(2)
        self.elapsed += dt
        while True:
            ph = self.phases[self._index]
            cmd, frac, finished = ph.step(self, self._t_phase, self._q, dt)
            if not finished:
                self._t_phase += dt
                break
            self._index += 1
            self._t_phase = 0.0
            if self._index == len(self.phases) or getattr(ph, "stop_all", False):
                self._finish(True, self._success_message())
                return np.zeros(2)
        i = self._index
        pct = 100.0 * (self._cum[i] + frac * (self._cum[i + 1] - self._cum[i]))
        self._percent = max(self._percent, min(pct, 99.9))
        return self._safe(cmd, dt)

    def _safe(self, cmd: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
        q = self._q
        cmd = np.clip(cmd, -self.vmax, self.vmax)
        q_next = np.clip(q + cmd * dt, np.minimum(self._lo, q), np.maximum(self._hi, q))
        return (q_next - q) / dt

    def _finish(self, success: bool, message: str) -> None:
        self._done = True
        self._success = success
        self._message = message
        if success:
            self._percent = 100.0

    def _success_message(self) -> str:
        return f"{self.name} complete"

    def cancel(self) -> bool:
        """Stop now: done, failed with "cancelled"; later commands are zero. False if done."""
        if self._done:
            return False
        self._finish(False, "cancelled")
        return True

    # -- reporting -------------------------------------------------------------
    @property
    def done(self) -> bool:
        """True once finished, failed (timeout) or cancelled."""
        return self._done

    @property
    def percent_complete(self) -> float:
        """Progress 0..100, monotonic; 100 only on success."""
        return self._percent

    @property
    def feedback(self) -> str:
        """A short human-readable progress line."""
        if self._done:
            return self._message
        return f"{self.phases[self._index].label} ({self._percent:.0f}%)"

    @property
    def joints(self) -> tuple[float, float]:
        """The last measured joints [pitch, roll] (rad)."""
        return float(self._q_raw[0]), float(self._q_raw[1])

    def result(self) -> tuple[bool, str, tuple[float, float]]:
        """``(success, message, final_joint_values)``; only once :attr:`done`."""
        if not self._done:
            raise RuntimeError(f"{self.name} is still running")
        return self._success, self._message, self.joints

    def status(self) -> PrimitiveStatus:
        """Feedback/result as the action reports it (``articutool.tool.api``)."""
        return PrimitiveStatus(
            name=self.name,
            percent_complete=self._percent,
            feedback=self.feedback,
            current_joint_values=self.joints,
            done=self._done,
            success=self._success,
            message=self._message,
            final_joint_values=self.joints if self._done else (),
        )
