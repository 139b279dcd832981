"""Food primitives: parameterised, stateful wrist motions (thesis §4.4; docs/hardware.md §6).

Pure: a primitive is built from its parameters, the spec and the joints at the start, then
stepped once per control tick with the *measured* joints; it returns a joint velocity command
``[pitch, roll]`` (rad/s) and keeps percent complete, feedback and, once done, a result.

Primitives (parameters in order; angles in rad unless ``_deg``):

- ``TWIRL_CW`` / ``TWIRL_CCW`` (rotations, speed_rad_s): roll ±2π·rotations.
- ``VIBRATE_ROLL`` (frequency_hz, amplitude_rad, duration_s): roll A·sin(2πft) about the start
  roll for the duration, then back to the start roll.
- ``TILT`` (target_roll_rad, velocity_rad_s, hold_s): roll to start + target, hold, roll back.
- ``NOODLE_SHED`` (pitch_up_deg, pitch_speed_rad_s, delay_s, vibrate_frequency_hz,
  vibrate_amplitude_deg, vibrate_duration_s): pitch up, wait, vibrate roll, pitch (and roll)
  back to the start.
- ``HOMING`` (speed_rad_s): both joints to zero.
- ``DEPOSIT_BITE`` (roll_angle_deg, roll_speed_rad_s, pause_s): roll by the angle from the
  start, pause, roll back to the start (upstream's registry; TILT in degrees).
- ``SETTLE_TOSS`` (tilt_angle_deg, tilt_speed_rad_s, flick_speed_rad_s): pitch the tip up by
  the angle at the tilt speed, flick it forward at the flick speed until it has passed the
  start pitch by ``spec.primitives.settle_toss_overshoot_rad``, return to the start at the
  tilt speed (upstream's registry: settles food in the spoon).
- ``VIBRATE_ROLL_UNTIL_STABLE`` (frequency_hz, amplitude_rad, max_duration_s, window_s,
  stable_g): VIBRATE_ROLL that ends when two consecutive windows (whole vibration periods)
  weigh the load, by the F/T sensor, within stable_g; at most max_duration_s (closed loop,
  thesis §7.1.2's future work).
- ``TILT_UNTIL_LOAD`` (step_rad, max_roll_rad, velocity_rad_s, target_load_g, window_s):
  weigh level; while above target_load_g, TILT to the next step (step, 2·step, … max_roll),
  roll back, weigh again for window_s (closed loop; at most max_roll/step tilts).

Conventions. CW is +roll: clockwise seen from the wrist looking along the utensil (+z of F0,
right-hand rule), the way a screw turns going in. TILT's target is relative to the roll at the
start (the levelled tool), and "back" is that start roll. NOODLE_SHED's "pitch up" raises the
utensil tip towards the tool's up vector (Eq. 4.1): pitch moves by −pitch_up when |θr| < π/2
at the start (since ∂(tip·up)/∂θp = −cos θr), by +pitch_up otherwise; SETTLE_TOSS's tilt is
the same "tip up" (upstream: "tilt back", −pitch at roll 0) and its flick the other way.
DEPOSIT_BITE and SETTLE_TOSS take upstream's parameters in upstream's units and meanings
(``personalrobotics/articutool_ros2``, ``articutool_control/primitives.py``); both return to
the start (upstream's DEPOSIT_BITE rolls back to roll 0, the same after a HOMING, but after a
twirl it would unwind whole turns the caller did not ask for).

Closed loop. Moves and returns are position-controlled on the measured joints: velocity =
``spec.primitives.position_gain`` × error, capped at the primitive's speed, done within
``position_tolerance``; joints not being moved are held the same way. TWIRL thus stops when the
measured roll travel (integrated tick by tick, robust to a wrapped reading) reaches 2π·rotations.
VIBRATE's command is the exact per-tick increment of A·sin(2πft) divided by dt, i.e. the tick
average of A·2πf·cos(2πft), so a zero-order-hold motor does not drift; its peak A·2πf must be
within the roll speed limit. A primitive running longer than ``timeout_factor`` × its nominal
duration + ``timeout_margin_s`` stops and fails (a stalled joint).

Safety (every tick, after the primitive's own command): per-joint clip to
``spec.wrist.max_velocity``; pitch kept within ``spec.wrist.pitch_limits`` and roll within the
cable budget ``±spec.wrist.roll_turn_budget`` turns, predictively (``q + q̇·dt`` clipped; a
joint already outside may only move back). Bad parameters raise :class:`PrimitiveError` naming
the parameter and the allowed range, before any motion.

Every primitive ends: a wait (TILT ``hold_s``, NOODLE_SHED ``delay_s``) is at most
``spec.primitives.max_hold_s``, a vibration at most ``max_vibrate_s``, and the whole nominal
motion at most ``max_duration_s`` (a slow speed cannot stretch it), so with the timeout no
primitive runs longer than ``timeout_factor × max_duration_s + timeout_margin_s``. That is what
lets the link's default policy finish a running primitive when the PC goes silent.

A new primitive is one class: subclass :class:`Primitive`, set ``name`` and
``parameter_names``, implement ``_plan`` (validate, return the phases) and decorate it with
:func:`register_primitive`.

Where it lives: this module is the registry and the library; the base class is
``primitive_base.py`` and the phases (moves, holds, vibrations, the F/T-weighing ones) are
``phases.py``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from articutool.spec import Spec
from articutool.tool.phases import (
    TWO_PI,
    Hold,
    Phase,
    Sweep,
    Vibrate,
    VibrateUntilStable,
    Weigh,
)
from articutool.tool.primitive_base import Primitive, PrimitiveError

__all__ = [
    "DepositBite",
    "Homing",
    "NoodleShed",
    "SettleToss",
    "Tilt",
    "TiltUntilLoad",
    "TwirlCCW",
    "TwirlCW",
    "VibrateRoll",
    "VibrateRollUntilStable",
    "get_primitive",
    "make_primitive",
    "primitive_names",
    "register_primitive",
    "unregister_primitive",
]

# ----------------------------------------------------------------------- registry --
_REGISTRY: dict[str, type[Primitive]] = {}
P = TypeVar("P", bound=type[Primitive])


def register_primitive(cls: P) -> P:
    """Class decorator: make ``cls`` available to :func:`make_primitive` under ``cls.name``."""
    if not (isinstance(cls, type) and issubclass(cls, Primitive)):
        raise TypeError(f"{cls!r} is not a Primitive subclass")
    if not cls.name or not isinstance(cls.name, str):
        raise ValueError(f"{cls.__name__}.name must be a non-empty string")
    if not all(isinstance(n, str) and n for n in cls.parameter_names):
        raise ValueError(f"{cls.__name__}.parameter_names must be a tuple of names")
    if cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls:
        raise ValueError(f"a primitive named {cls.name!r} is already registered")
    _REGISTRY[cls.name] = cls
    return cls


def unregister_primitive(name: str) -> None:
    """Remove a registered primitive (for plug-ins and tests)."""
    _REGISTRY.pop(name, None)


def primitive_names() -> list[str]:
    """The registered primitive names, sorted."""
    return sorted(_REGISTRY)


def get_primitive(name: str) -> type[Primitive]:
    """The class registered as ``name``; unknown names list the known ones."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise PrimitiveError(
            f"unknown primitive {name!r}; known: {', '.join(primitive_names())}"
        ) from None


def make_primitive(name: str, params: Sequence[float], spec: Spec, q_start: ArrayLike) -> Primitive:
    """Build primitive ``name`` for a wrist now at ``q_start``; refusals raise PrimitiveError."""
    return get_primitive(name)(params, spec, q_start)


# --------------------------------------------------------------------- primitives --
class _Twirl(Primitive):
    parameter_names = ("rotations", "speed_rad_s")
    direction: ClassVar[float] = 1.0

    def _plan(self, rotations: float, speed: float) -> list[Phase]:
        self._require("rotations", rotations, 0.0, math.inf, lo_open=True, unit="turns")
        self._speed("speed_rad_s", speed, 1)
        end = self.q_start + np.array([0.0, self.direction * TWO_PI * rotations])
        room = max(self.roll_bound - self.direction * self.q_start[1], 0.0) / TWO_PI
        self._roll_in_budget("rotations", float(end[1]), f"; at most {room:.2f} turns this way")
        return [self.move("twirl", self.q_start, end, speed)]

    @property
    def turns(self) -> float:
        """Measured roll travel so far, in turns, in the twirl's direction."""
        return self.direction * (self._q[1] - self.q_start[1]) / TWO_PI

    @property
    def feedback(self) -> str:
        if self._done:
            return self._message
        return f"twirl {self.turns:.2f}/{self.params[0]:g} turns"

    def _success_message(self) -> str:
        return f"{self.name} complete: {self.turns:.2f} turns"


@register_primitive
class TwirlCW(_Twirl):
    """Twirl clockwise (+roll) by ``rotations`` turns at ``speed_rad_s``."""

    name = "TWIRL_CW"
    direction = 1.0


@register_primitive
class TwirlCCW(_Twirl):
    """Twirl counter-clockwise (−roll) by ``rotations`` turns at ``speed_rad_s``."""

    name = "TWIRL_CCW"
    direction = -1.0


def _vibration_checks(
    prim: Primitive, f_name: str, a_name: str, f: float, a: float, a_unit: str, a_scale: float
) -> None:
    nyquist = 0.5 * prim.spec.wrist.loop_rate_hz
    prim._require(
        f_name,
        f,
        0.0,
        nyquist,
        lo_open=True,
        hi_open=True,
        unit="Hz",
        why="below half the control loop rate",
    )
    amp = a * a_scale
    vmax = float(prim.vmax[1])
    prim._require(a_name, a, 0.0, math.inf, lo_open=True, unit=a_unit)
    peak = amp * TWO_PI * f
    if peak > vmax:
        raise PrimitiveError(
            f"{prim.name}: parameters '{a_name}' × 2π × '{f_name}' give a peak roll speed of "
            f"{peak:.3g} rad/s, above the roll speed limit {vmax:g} rad/s "
            f"(spec.wrist.max_velocity); '{a_name}' must be ≤ {vmax / (TWO_PI * f) / a_scale:.4g} "
            f"{a_unit} at this frequency"
        )
    for s in (1.0, -1.0):
        prim._roll_in_budget(a_name, float(prim.q_start[1] + s * amp))


@register_primitive
class VibrateRoll(Primitive):
    """Roll vibration A·sin(2πft) about the start roll for a duration, then back to it."""

    name = "VIBRATE_ROLL"
    parameter_names = ("frequency_hz", "amplitude_rad", "duration_s")

    def _plan(self, f: float, a: float, duration: float) -> list[Phase]:
        _vibration_checks(self, "frequency_hz", "amplitude_rad", f, a, "rad", 1.0)
        self._max_duration("duration_s", duration, "max_vibrate_s")
        peak = a * TWO_PI * f
        q0 = self.q_start
        return [
            Vibrate("vibrate", q0, [peak, peak], f, a, duration),
            self.move("return", q0 + [0.0, a], q0, peak),
        ]


@register_primitive
class Tilt(Primitive):
    """Roll by ``target_roll_rad`` from the start, hold ``hold_s``, roll back (thesis §4.4)."""

    name = "TILT"
    parameter_names = ("target_roll_rad", "velocity_rad_s", "hold_s")

    def _plan(self, target: float, velocity: float, hold: float) -> list[Phase]:
        return _roll_out_and_back(self, ("target_roll_rad", "velocity_rad_s", "hold_s"),
                                  target, "rad", 1.0, velocity, hold, ("tilt", "hold"))


def _roll_out_and_back(prim: Primitive, names: tuple[str, str, str], angle: float, unit: str,
                       scale: float, velocity: float, hold: float,
                       labels: tuple[str, str]) -> list[Phase]:
    """Roll by ``angle`` × ``scale`` rad from the start, hold ``hold`` s, roll back (TILT,
    DEPOSIT_BITE); ``names`` are the three parameters' names for the refusals."""
    lo, hi = prim.spec.wrist.roll_limits
    prim._require(names[0], angle, lo / scale, hi / scale, unit=unit,
                  why="relative to the start roll, spec.wrist.roll_limits")
    prim._speed(names[1], velocity, 1)
    prim._max_duration(names[2], hold, "max_hold_s")
    q0 = prim.q_start
    tilted = q0 + [0.0, angle * scale]
    prim._roll_in_budget(names[0], float(tilted[1]))
    return [
        prim.move(labels[0], q0, tilted, velocity),
        Hold(labels[1], tilted, [velocity, velocity], hold),
        prim.move("return", tilted, q0, velocity),
    ]


@register_primitive
class DepositBite(Primitive):
    """Roll by ``roll_angle_deg`` from the start, pause ``pause_s``, roll back to the start
    (upstream's DEPOSIT_BITE: parameters [roll_angle_deg, roll_speed_rps, pause_sec])."""

    name = "DEPOSIT_BITE"
    parameter_names = ("roll_angle_deg", "roll_speed_rad_s", "pause_s")

    def _plan(self, angle_deg: float, speed: float, pause: float) -> list[Phase]:
        return _roll_out_and_back(self, self.parameter_names, angle_deg, "deg",  # type: ignore[arg-type]
                                  math.pi / 180.0, speed, pause, ("deposit", "pause"))


def _tip_up_sign(q0: ArrayLike) -> float:
    """The pitch direction that raises the utensil tip (see the module docstring)."""
    return -1.0 if math.cos(float(np.asarray(q0)[1])) >= 0.0 else 1.0


@register_primitive
class SettleToss(Primitive):
    """Tilt the tip up, flick it forward past the start, return (upstream's SETTLE_TOSS:
    parameters [tilt_angle_deg, tilt_speed_rps, flick_speed_rps])."""

    name = "SETTLE_TOSS"
    parameter_names = ("tilt_angle_deg", "tilt_speed_rad_s", "flick_speed_rad_s")

    def _plan(self, tilt_deg: float, tilt_speed: float, flick_speed: float) -> list[Phase]:
        q0 = self.q_start
        lo, hi = self.spec.wrist.pitch_limits
        sign = _tip_up_sign(q0)
        over = self.spec.primitives.settle_toss_overshoot_rad
        room = (q0[0] - lo) if sign < 0 else (hi - q0[0])
        deg = math.degrees
        why = (f"from pitch {deg(q0[0]):.1f}° within spec.wrist.pitch_limits "
               f"[{deg(lo):.1f}°, {deg(hi):.1f}°]")
        self._require("tilt_angle_deg", tilt_deg, 0.0, max(deg(room), 0.0), lo_open=True,
                      unit="deg", why=why)
        past = q0[0] - sign * over
        if not lo <= past <= hi:
            raise PrimitiveError(
                f"{self.name}: the flick passes the start pitch {deg(q0[0]):.1f}° by "
                f"{deg(over):.1f}° (spec.primitives.settle_toss_overshoot_rad), beyond "
                f"spec.wrist.pitch_limits [{deg(lo):.1f}°, {deg(hi):.1f}°]; start nearer level")
        self._speed("tilt_speed_rad_s", tilt_speed, 0)
        self._speed("flick_speed_rad_s", flick_speed, 0)
        up = q0 + [sign * math.radians(tilt_deg), 0.0]
        flick = q0 + [-sign * over, 0.0]
        hold = float(self.vmax[1])  # roll is held at the start
        return [
            self.move("tilt back", q0, up, [tilt_speed, hold]),
            Sweep("flick", up, flick, [flick_speed, hold], joint=0),
            self.move("return", flick, q0, [tilt_speed, hold]),
        ]


@register_primitive
class NoodleShed(Primitive):
    """Pitch up, wait, vibrate roll, return pitch and roll to the start (thesis §4.4)."""

    name = "NOODLE_SHED"
    parameter_names = (
        "pitch_up_deg",
        "pitch_speed_rad_s",
        "delay_s",
        "vibrate_frequency_hz",
        "vibrate_amplitude_deg",
        "vibrate_duration_s",
    )

    def _plan(
        self,
        up_deg: float,
        pitch_speed: float,
        delay: float,
        f: float,
        a_deg: float,
        vib_duration: float,
    ) -> list[Phase]:
        q0 = self.q_start
        lo, hi = self.spec.wrist.pitch_limits
        sign = _tip_up_sign(q0)
        room = (q0[0] - lo) if sign < 0 else (hi - q0[0])
        deg = math.degrees
        why = f"from pitch {deg(q0[0]):.1f}° within spec.wrist.pitch_limits "
        why += f"[{deg(lo):.1f}°, {deg(hi):.1f}°]"
        self._require(
            "pitch_up_deg", up_deg, 0.0, max(deg(room), 0.0), lo_open=True, unit="deg", why=why
        )
        self._speed("pitch_speed_rad_s", pitch_speed, 0)
        self._max_duration("delay_s", delay, "max_hold_s")
        _vibration_checks(
            self, "vibrate_frequency_hz", "vibrate_amplitude_deg", f, a_deg, "deg", math.pi / 180.0
        )
        self._max_duration("vibrate_duration_s", vib_duration, "max_vibrate_s")
        a = math.radians(a_deg)
        peak = a * TWO_PI * f
        up = q0 + [sign * math.radians(up_deg), 0.0]
        speeds = [pitch_speed, peak]
        return [
            self.move("pitch up", q0, up, speeds),
            Hold("settle", up, speeds, delay),
            Vibrate("vibrate", up, speeds, f, a, vib_duration),
            self.move("return", up + [0.0, a], q0, speeds),
        ]


@register_primitive
class Homing(Primitive):
    """Both joints to zero (roll to zero net turns: unwinds the cable)."""

    name = "HOMING"
    parameter_names = ("speed_rad_s",)

    def _plan(self, speed: float) -> list[Phase]:
        vmax = float(self.vmax.min())
        self._require(
            "speed_rad_s",
            speed,
            0.0,
            vmax,
            lo_open=True,
            unit="rad/s",
            why="both joints' speed limit, spec.wrist.max_velocity",
        )
        return [self.move("homing", self.q_start, np.zeros(2), speed)]


# ------------------------------------------------------- closed-loop (F/T) shedding --
def _window_check(prim: Primitive, pname: str, window: float, f: float | None) -> float:
    lo = 1.0 / f if f else 2.0 / prim.spec.ft.rate_hz
    why = "at least one vibration period" if f else "at least two F/T samples"
    prim._require(pname, window, lo, prim.spec.primitives.max_hold_s, unit="s",
                  why=f"{why}, at most spec.primitives.max_hold_s")
    if f:  # whole periods: the roll's effect on the reading averages out
        return max(1, round(window * f)) / f
    return window


@register_primitive
class VibrateRollUntilStable(Primitive):
    """VIBRATE_ROLL that stops when the F/T-weighed load stops changing (at most
    ``max_duration_s``), then returns to the start roll. Thesis §4.4 + §7.1.2."""

    name = "VIBRATE_ROLL_UNTIL_STABLE"
    parameter_names = ("frequency_hz", "amplitude_rad", "max_duration_s", "window_s",
                       "stable_g")
    needs_ft = True

    def _plan(self, f: float, a: float, duration: float, window: float,
              stable: float) -> list[Phase]:
        _vibration_checks(self, "frequency_hz", "amplitude_rad", f, a, "rad", 1.0)
        self._max_duration("max_duration_s", duration, "max_vibrate_s")
        window = _window_check(self, "window_s", window, f)
        self._require("stable_g", stable, 0.0, math.inf, lo_open=True, unit="g")
        peak = a * TWO_PI * f
        q0 = self.q_start
        self.vib = VibrateUntilStable("vibrate", q0, [peak, peak], f, a, duration, window,
                                      stable, self.spec.imu.gravity)
        return [self.vib, self.move("return", q0 + [0.0, a], q0, peak)]

    def _success_message(self) -> str:
        w = self.vib.weights
        how = "load stable" if self.vib.settled else "time bound, load still changing"
        last = f", {w[-1]:.2f} g" if w else ", no F/T samples"
        return f"{self.name} complete: {how} after {len(w)} windows{last}"


@register_primitive
class TiltUntilLoad(Primitive):
    """TILT in growing steps (``step_rad``, ``2·step_rad``, … up to ``max_roll_rad``), each
    tilt rolled back and the load weighed level for ``window_s``; stops as soon as the load
    is at most ``target_load_g``. Thesis §4.4 + §7.1.2."""

    name = "TILT_UNTIL_LOAD"
    parameter_names = ("step_rad", "max_roll_rad", "velocity_rad_s", "target_load_g",
                       "window_s")
    needs_ft = True

    def _plan(self, step: float, max_roll: float, velocity: float, target_g: float,
              window: float) -> list[Phase]:
        lo, hi = self.spec.wrist.roll_limits
        self._require("max_roll_rad", max_roll, lo, hi, unit="rad",
                      why="relative to the start roll, spec.wrist.roll_limits")
        self._require("step_rad", step, 0.0, max(abs(max_roll), 1e-9), lo_open=True,
                      unit="rad", why="one tilt step, at most |max_roll_rad|")
        self._speed("velocity_rad_s", velocity, 1)
        self._require("target_load_g", target_g, 0.0, math.inf, unit="g")
        window = _window_check(self, "window_s", window, None)
        q0 = self.q_start
        self._roll_in_budget("max_roll_rad", float(q0[1] + max_roll))
        g, sign = self.spec.imu.gravity, math.copysign(1.0, max_roll)
        n = max(1, math.ceil(abs(max_roll) / step - 1e-9))
        self.weighs: list[Weigh] = [Weigh("weigh", q0, [velocity] * 2, window, target_g, g)]
        phases: list[Phase] = [self.weighs[0]]
        for k in range(1, n + 1):
            tilted = q0 + [0.0, sign * min(k * step, abs(max_roll))]
            self.weighs.append(Weigh("weigh", q0, [velocity] * 2, window, target_g, g))
            phases += [self.move(f"tilt {k}", q0, tilted, velocity),
                       self.move("return", tilted, q0, velocity), self.weighs[-1]]
        return phases

    def _success_message(self) -> str:
        done = [w.grams for w in self.weighs if w.grams is not None]
        tilts = sum(1 for w in self.weighs[1:] if w.finished)
        how = "load at target" if any(w.stop_all for w in self.weighs) else \
            "bound reached, load above target"
        last = f", {done[-1]:.2f} g" if done else ", no F/T samples"
        return f"{self.name} complete: {how} after {tilts} tilts{last}"
