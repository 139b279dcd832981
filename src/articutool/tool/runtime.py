"""The onboard tool runtime: the 50 Hz loop and its mode state machine (thesis §3.2, §4.2, §4.4).

:class:`ToolRuntime` implements :class:`~articutool.tool.api.ToolAPI`. It is the imperative
shell around the pure pieces: each tick it reads the drivers, runs the complementary filter
(``filter.py``) and, depending on the mode, the leveling controller (``controller.py``,
Alg. 1), a primitive (``primitives.py``) or a wrist trajectory, and writes one joint velocity
command.

Modes (``Mode``):

- ``DISABLED``: the motors are commanded to zero velocity every tick; torque stays on, so
  the joints hold where they are (a hardware error may have dropped torque on one motor).
- ``LEVELING``: filter + :class:`LevelingController` with the pitch/roll offsets (degrees)
  given to :meth:`ToolRuntime.set_mode`. The bias-corrected gyro is fed forward (Eq. 4.5) to
  cancel the base's own rotation unless ``rate_feedforward=False``. A stall (the controller
  at rest short of level, :attr:`LevelingController.stalled`) is no fault: the tool keeps
  leveling, and ``extra`` reports ``leveling_stalled`` = 1 with the tilt and the nearest
  reachable level configuration (``leveling_target_pitch``/``_roll``, rad; NaN when none is
  reachable), so the PC sees it.
- ``FULL_ORIENTATION``: the same loop holding a target utensil orientation given as a
  quaternion in a gravity-aligned robot base (:func:`~articutool.tool.modes.attitude_target`:
  the two degrees of freedom gravity fixes; the heading about the vertical follows the arm,
  the wrist having no heading reference) with an
  :class:`~articutool.tool.controller.AttitudeController`: leveling's envelope, IMU check,
  faults and stall report. A target no configuration within the pitch limits holds is refused
  (nothing moves); one the base's motion takes out of reach is held as near as the limits
  allow and reported stalled, like leveling.
- ``PRIMITIVE``: a primitive from :func:`~articutool.tool.primitives.make_primitive`; when it
  finishes the runtime returns to ``DISABLED`` and keeps its result.
- ``TRAJECTORY``: follows a wrist :class:`~articutool.trajectory.JointTrajectory` (e.g. the
  verifier's synchronised leveling trajectory): ``q̇ = q̇_ref(t) + K (q_ref(t) − q)`` with
  ``K = spec.primitives.position_gain``, then holds the last point until the mode changes.
  A ``start_delay`` (a ``header.stamp`` in the future, synchronised with the arm) holds the
  present position until then, as ROS trajectory controllers do.

Rules (thesis §4.4, docs/hardware.md §6): a primitive is refused while leveling, while another
runs and while a fault is set; any mode change aborts a running primitive (its result is
``success=False``, message "aborted by mode change to …").

Safety — every fault stops the motors, switches to ``DISABLED`` and sets ``fault`` (the first
cause is kept, sticky):

- motor hardware error (any mode) or a failed motor read;
- joint-limit violation (any mode): a measured joint outside the safety envelope, pitch
  ``spec.wrist.pitch_limits`` and roll ``±spec.wrist.roll_turn_budget`` turns (the cable), each
  widened by the distance one tick covers at the commandable speed (``max_velocity / rate``,
  i.e. one tick of overshoot). The per-mode limits (leveling's ``roll_limits``, trajectory
  validation, the primitives' budget) are tighter and enforced by the mode itself;
- IMU data older than two loop periods **while LEVELING** (the only mode whose command uses
  the IMU). In the other modes a stale IMU is reported (``extra["imu_stale"]``) but does not
  stop a primitive or a trajectory, which run on the joint encoders; entering LEVELING with a
  stale IMU is refused;
- a non-finite command, or any exception raised inside the tick (no exception escapes the
  loop; the traceback is logged);
- a stop the motors do not confirm (``MotorDriver.stop`` raised): they may still run at their
  last command, which telemetry keeps reporting (``command_*`` is what was last written, zero
  only once a stop is confirmed); the motors' bus watchdog stops them
  ``spec.motors.bus_watchdog_s`` after the last packet. The cause is gone once a stop is
  confirmed (DISABLED retries every tick).

The fault is cleared by the next successful :meth:`~ToolRuntime.set_mode` only when its cause
is gone (fresh IMU, no hardware error, motors answering). ``set_mode(DISABLED)`` always
succeeds but keeps a fault whose cause persists. A motor hardware error persists until the
motors are rebooted, and only an explicit :meth:`~ToolRuntime.clear_fault` does that (the next
tick calls ``MotorDriver.clear_errors`` and re-enables torque), refused while a motor is at or
above ``spec.motors.reboot_below_c`` (an overheating shutdown stays until it has cooled); no
mode request reboots anything. For a limit violation ``set_mode`` clears the fault and arms a
recovery: while a joint is outside the envelope, commands that drive it further out fault
again, while commands that bring it back are allowed (e.g. LEVELING, HOMING).

Threading: every public method and :meth:`tick` hold one re-entrant lock, so API calls from
the link's threads are serialised with the loop and may safely touch the drivers (e.g. stop
the motors at once when a primitive is cancelled). A tick costs well under a millisecond
(``benchmarks/test_bench_tick.py``), so callers wait at most that.

Timing: :meth:`tick` does one deterministic iteration at a given time (tests step the
simulated wrist and the runtime alternately, faster than real time); :meth:`run` is the
real-time loop (absolute deadlines on ``time.monotonic``, no drift; a late tick counts as an
overrun and skips the missed periods instead of bursting).

Power: ``battery_voltage`` is the motors' input voltage. ``extra`` carries an energy
estimate from the spec's power budget (thesis §3.1: idle in DISABLED, leveling in LEVELING,
peak — an upper bound — in PRIMITIVE/TRAJECTORY), integrated since start:
``battery_used_wh`` and ``battery_remaining_pct`` (assumes the bank held
``battery_start_pct`` at start; the 12 V supply is regulated, so the voltage alone says little
about the charge) and ``battery_runtime_h`` at the present mode's power.

Composition: this module is the state machine, the loop and the fault handling; the parts it
composes are their own modules: ``modes.py`` (mode requests, LEVELING), ``envelope.py`` (the
safety envelope and limit recovery), ``following.py`` (TRAJECTORY: validation and following),
``sensing.py`` (IMU → filter, freshness, F/T) and ``telemetry.py`` (loop statistics, energy,
the state snapshot). What stays here is one unit on purpose: the ToolAPI calls, the tick and
the fault transitions read and write the same mode and fault state under one lock, and split
apart each would have to reach into the others' state.
"""

from __future__ import annotations

import enum
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from articutool.rotations import quaternion_to_matrix
from articutool.spec import Spec
from articutool.tool.api import (
    ABORTED_BY_MODE_CHANGE,
    IDENTITY_XYZW,
    Mode,
    PrimitiveStatus,
    ToolState,
)
from articutool.tool.controller import AttitudeController, LevelingController
from articutool.tool.drivers.base import FTDriver, ImuDriver, MotorDriver, MotorState
from articutool.tool.envelope import SafetyEnvelope
from articutool.tool.filter import ComplementaryFilter
from articutool.tool.following import TrajectoryFollower
from articutool.tool.kinematics import tilt_from_vertical, up_vector
from articutool.tool.modes import Leveling, attitude_target, check_offsets, requested_mode
from articutool.tool.primitive_base import Primitive, PrimitiveError
from articutool.tool.primitives import make_primitive
from articutool.tool.sensing import STALE_IMU_PERIODS, Sensing
from articutool.tool.telemetry import EnergyMeter, LoopStats, build_state
from articutool.trajectory import JointTrajectory, TrajectoryError

__all__ = ["FaultKind", "ToolRuntime"]

log = logging.getLogger(__name__)


class FaultKind(enum.Enum):
    """What put the tool in its safe state; it decides how the fault clears
    (:meth:`ToolRuntime.clear_fault`): a cause that persists refuses the clear, a motor
    hardware error needs a reboot, a joint-limit fault arms the envelope's recovery."""

    EXCEPTION = "exception"  # the control loop or the state it publishes raised
    MOTOR_READ = "motor_read"  # the motors did not answer or gave invalid joints
    HARDWARE = "hardware"  # a motor reported a hardware error (overload, overheating, …)
    LIMIT = "limit"  # the safety envelope: a joint or velocity limit
    IMU_STALE = "imu_stale"  # no fresh IMU data while leveling
    COMMAND = "command"  # the mode computed a non-finite joint command
    MOTOR_STOP = "motor_stop"  # the motors did not confirm a stop


class ToolRuntime:
    """The 50 Hz tool loop and mode state machine; implements ``ToolAPI`` (see module doc).

    Args:
        spec: the hardware spec (rates, limits, gains, power budget).
        motors, imu, ft: drivers (``articutool.tool.drivers``); ``ft`` is optional. They are
            opened by :meth:`open` (or ``with runtime:``), not by the constructor.
        clock: monotonic seconds; must be the clock of the drivers' sample stamps (the
            simulated wrist's ``sim.clock`` with the sim drivers, ``time.monotonic`` on the
            hardware).
        R_base_imu: mounting rotation of the IMU on the tool base, ``R_F0←imu`` (its columns
            are the IMU axes expressed in F0; identity: IMU axes are F0's). ``SimWrist`` takes
            the same matrix under the same name.
        rate_feedforward: add the gyro feed-forward (Eq. 4.5) to the leveling controller.
        battery_start_pct: assumed charge at start for the energy estimate.
    """

    def __init__(
        self,
        spec: Spec,
        motors: MotorDriver,
        imu: ImuDriver,
        ft: FTDriver | None = None,
        clock: Callable[[], float] = time.monotonic,
        *,
        R_base_imu: NDArray[np.float64] | None = None,
        rate_feedforward: bool = True,
        battery_start_pct: float = 100.0,
    ) -> None:
        self._energy = EnergyMeter(spec, battery_start_pct)  # validates battery_start_pct
        self.spec = spec
        self.motors = motors
        self.imu = imu
        self.ft = ft
        self.clock = clock
        w = spec.wrist
        self.period = w.period
        self.joint_names: tuple[str, str] = (w.joint_names[0], w.joint_names[1])
        self._vmax = w.velocity_limits
        self._limits = w.limits

        self.filter = ComplementaryFilter.from_spec(spec.filter)
        self.controller = LevelingController.from_spec(spec, R_base_imu=R_base_imu)
        self.stats = LoopStats()
        self._envelope = SafetyEnvelope(spec)
        self._sensing = Sensing(spec, imu, ft, self.filter)
        self._leveling = Leveling(spec, self.controller, rate_feedforward)
        self._attitude = Leveling(spec, AttitudeController.from_spec(spec, R_base_imu=R_base_imu),
                                  rate_feedforward)
        self._follower = TrajectoryFollower(spec)
        self._lock = threading.RLock()
        self._link_work: Callable[[], None] | None = None
        self._opened = False
        self._wall_timing = False

        self._mode = Mode.DISABLED
        self._fault = ""
        self._fault_kind: FaultKind | None = None
        self._faults_total = 0
        self._stop_ok = True  # the last motors.stop() was confirmed
        self._stop_failures = 0
        self._in_stop_fault = False
        self._reboot_requested = False
        self._motor_state: MotorState | None = None
        self._motor_read_ok = False
        self._tilt = math.nan
        self._primitive: Primitive | None = None
        self._primitive_status: PrimitiveStatus | None = None
        # loop bookkeeping
        self._last_now: float | None = None
        self._command = np.zeros(2)
        self._snapshot: ToolState | None = None

    # ----------------------------------------------------------------- lifecycle --
    def open(self) -> None:
        """Open the drivers; motors in velocity mode, zero goal, torque on (holding)."""
        with self._lock:
            self.motors.open()
            self.motors.set_mode("velocity")
            self.motors.enable_torque(True)
            self.imu.open()
            if self.ft is not None:
                self.ft.open()
                self.ft.tare()
            self._opened = True

    def close(self) -> None:
        """Stop the motors, torque off, close every driver (best effort, never raises)."""
        with self._lock:
            self._abort_primitive("aborted: runtime shutting down")
            self._follower.drop()
            self._mode = Mode.DISABLED
            self._stop_motors()
            for what, fn in (
                ("torque off", lambda: self.motors.enable_torque(False)),
                ("close motors", self.motors.close),
                ("close IMU", self.imu.close),
                ("close F/T", self.ft.close if self.ft is not None else lambda: None),
            ):
                try:
                    fn()
                except Exception:
                    log.exception("%s failed during shutdown", what)
            self._opened = False

    def __enter__(self) -> ToolRuntime:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------- ToolAPI --
    def set_mode(
        self, mode: Mode | int, pitch_offset_deg: float = 0.0, roll_offset_deg: float = 0.0,
        target_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW,
    ) -> tuple[bool, str]:
        """Switch to DISABLED, LEVELING (offsets in degrees) or FULL_ORIENTATION (the utensil
        held at ``target_xyzw``, [x, y, z, w] in a gravity-aligned robot base); aborts a
        running primitive.

        Refused, with no change, for other modes, bad offsets or target, a persisting fault
        (except DISABLED) or, for LEVELING and FULL_ORIENTATION, no fresh IMU data or joint
        state; FULL_ORIENTATION also for a target out of the wrist's reach.
        """
        offsets = (0.0, 0.0)
        g = None
        try:
            mode = requested_mode(mode)
            if mode is Mode.LEVELING:
                offsets = check_offsets(pitch_offset_deg, roll_offset_deg, self._limits)
            if mode is Mode.FULL_ORIENTATION:
                g = attitude_target(target_xyzw)
        except ValueError as err:
            return False, str(err)
        steering = mode in (Mode.LEVELING, Mode.FULL_ORIENTATION)
        with self._lock:
            note = ""
            if self._fault:
                cause = self._fault_cause()
                if cause:
                    if self._fault_kind is FaultKind.HARDWARE:
                        cause += "; clear_fault reboots the motors (once the cause is gone)"
                    if steering:
                        return False, f"refused: fault persists: {cause}"
                    self._enter(Mode.DISABLED)
                    return True, f"DISABLED; fault persists: {cause}"
                note = f" (cleared fault: {self._fault})"
                self._clear_fault()
            if steering:
                if self._motor_state is None:
                    return False, "refused: no joint state yet (the loop has not run)"
                if not self._sensing.imu_fresh or not self.filter.initialized:
                    return False, ("refused: no fresh IMU data (older than "
                                   f"{STALE_IMU_PERIODS:g} loop periods); cannot level")
                q = np.asarray(self._motor_state.position, dtype=np.float64)
                R = self.controller.tool_base_orientation(
                    quaternion_to_matrix(self.filter.orientation))
                if mode is Mode.FULL_ORIENTATION:
                    att = self._attitude
                    previous = att.controller.target_vector  # type: ignore[attr-defined]
                    att.controller.set_target(g)  # type: ignore[attr-defined]
                    refusal = att.engage(R, q, (0.0, 0.0))
                    if refusal:
                        att.controller.set_target(previous)  # type: ignore[attr-defined]
                        return False, refusal
                    self._enter(Mode.FULL_ORIENTATION)
                    return True, ("FULL_ORIENTATION holding the target's attitude against "
                                  "gravity (the heading about the vertical follows the arm: "
                                  f"no heading reference on the wrist){note}")
                refusal = self._leveling.engage(R, q, offsets)
                if refusal:
                    return False, refusal
                self._enter(Mode.LEVELING)
                return True, (f"LEVELING with offsets pitch {offsets[0]:g}°, "
                              f"roll {offsets[1]:g}°{note}")
            self._enter(Mode.DISABLED)
            return True, f"DISABLED{note}"

    def clear_fault(self) -> tuple[bool, str]:
        """Explicitly clear the fault; the mode stays DISABLED.

        A fault whose cause is gone is cleared now. A motor hardware error needs a reboot: it
        is requested for the next tick (``MotorDriver.clear_errors``, then torque on) unless a
        motor is still at or above ``spec.motors.reboot_below_c``; the fault clears at the next
        ``set_mode`` once the motors report no error. Other persisting causes are refused.
        """
        with self._lock:
            if not self._fault:
                return False, "no fault to clear"
            cause = self._fault_cause()
            if not cause:
                message = f"cleared fault: {self._fault}"
                self._clear_fault()
                return True, message
            if self._fault_kind is not FaultKind.HARDWARE:
                return False, f"refused: fault persists: {cause}"
            ms = self._motor_state
            limit = self.spec.motors.reboot_below_c
            if ms is not None and ms.temperature >= limit:
                return False, (f"refused: a motor is at {ms.temperature:.0f} °C; it is rebooted "
                               f"only below {limit:g} °C (spec.motors.reboot_below_c): let it "
                               "cool, then clear_fault again")
            self._reboot_requested = True
            return True, ("rebooting the motors on the next tick; set_mode clears the fault "
                          "once they report no error")

    def start_primitive(self, name: str, parameters: list[float]) -> tuple[bool, str]:
        """Start primitive ``name``; refused while leveling, while another runs, while a
        fault is set, before the first tick, or when the primitive refuses its parameters."""
        with self._lock:
            if self._fault:
                return False, (f"refused: fault active ({self._fault}); "
                               "clear it first (set_mode; clear_fault for a hardware error)")
            if self._mode in (Mode.LEVELING, Mode.FULL_ORIENTATION):
                return False, (f"refused while {self._mode.name.lower().replace('_', ' ')}; "
                               "set_mode(DISABLED) first")
            if self._primitive is not None:
                return False, f"refused: primitive {self._primitive.name} is running"
            if self._motor_state is None:
                return False, "refused: no joint state yet (the loop has not run)"
            try:
                prim = make_primitive(str(name), list(parameters), self.spec,
                                      self._motor_state.position.copy())
            except (PrimitiveError, ValueError, TypeError) as err:
                return False, str(err)
            if prim.needs_ft and self.ft is None:
                return False, f"refused: {prim.name} reads the F/T sensor and this tool has none"
            self._enter(Mode.PRIMITIVE)
            self._primitive = prim
            self._primitive_status = prim.status()
            return True, f"started {prim.name} {list(prim.params)}"

    def primitive_status(self) -> PrimitiveStatus | None:
        """Progress of the running primitive, or the result of the last (None if never)."""
        with self._lock:
            return self._primitive_status

    def cancel_primitive(self) -> bool:
        """Cancel the running primitive: motors stop now, mode DISABLED. False if none ran."""
        with self._lock:
            if self._primitive is None:
                return False
            self._abort_primitive("cancelled")
            self._enter(Mode.DISABLED)
            return True

    def follow_trajectory(
        self, trajectory: JointTrajectory, start_delay: float = 0.0
    ) -> tuple[bool, str]:
        """Enter TRAJECTORY and follow ``trajectory`` (joints: the wrist's [pitch, roll]).

        ``start_delay`` (s): the trajectory's time 0 is that long after this call (a
        ``header.stamp`` in the future); until then the wrist holds its present position. Zero
        or negative starts at the next tick.

        Refused, with no motion, when a fault is set, before the first tick, or when the
        trajectory is invalid: other joint names, a last point or a start more than
        ``spec.primitives.max_duration_s`` away, a position outside ``spec.wrist`` limits or
        a velocity above ``spec.wrist.max_velocity`` (waypoints and the interpolated spline),
        or a first point at t = 0 farther than one tick's travel from the present joints
        (give it a later ``time_from_start`` and the runtime moves there smoothly).
        """
        with self._lock:
            if self._fault:
                return False, (f"refused: fault active ({self._fault}); "
                               "clear it first (set_mode; clear_fault for a hardware error)")
            if self._motor_state is None:
                return False, "refused: no joint state yet (the loop has not run)"
            try:
                delay = float(start_delay)
            except (TypeError, ValueError):
                delay = math.nan
            if not math.isfinite(delay):
                return False, f"trajectory refused: start_delay must be finite; got {start_delay!r}"
            if delay > self._follower.max_duration:
                return False, (f"trajectory refused: it starts {delay:g} s from now, more than "
                               f"{self._follower.max_duration:g} s "
                               "(spec.primitives.max_duration_s): are the PC's and the tool's "
                               "clocks synchronised?")
            try:
                traj = self._follower.validated(trajectory, self._motor_state.position)
            except (TrajectoryError, ValueError, TypeError) as err:
                return False, f"trajectory refused: {err}"
            self._enter(Mode.TRAJECTORY)
            # Without a delay, time 0 is the first TRAJECTORY tick; with one, it is absolute.
            self._follower.start(traj, float(self.clock()) + delay if delay > 0.0 else None)
            when = f"in {delay:.3f} s" if delay > 0.0 else "now"
            return True, (f"following {len(traj)} points over {traj.duration:.3f} s starting "
                          f"{when}, then holding the last point")

    def state(self) -> ToolState:
        """The latest snapshot (mode and fault are current even between ticks)."""
        with self._lock:
            snap = self._snapshot if self._snapshot is not None else self._make_state(
                self.clock())
            if snap.mode is not self._mode or snap.fault != self._fault:
                snap = replace(snap, mode=self._mode, fault=self._fault)
            return snap

    # ------------------------------------------------------------ extra queries --
    @property
    def mode(self) -> Mode:
        """The current mode."""
        return self._mode

    @property
    def fault(self) -> str:
        """Why the motors were stopped; empty when healthy."""
        return self._fault

    @property
    def motors_stopped(self) -> bool:
        """Whether the last stop sent to the motors was confirmed."""
        return self._stop_ok

    def reset_stats(self) -> None:
        """Forget the loop timing statistics (e.g. after start-up)."""
        with self._lock:
            self.stats.reset()

    # ----------------------------------------------------------------- the loop --
    def run(self, stop_event: threading.Event) -> None:
        """The real-time loop: :meth:`tick` every ``spec.wrist.period`` until ``stop_event``.

        Absolute deadlines on ``time.monotonic`` (no drift); a tick that ends after the next
        deadline is an overrun and the missed periods are skipped. While it runs, the period
        statistics are the wake-up intervals on ``time.monotonic`` (real jitter), not the
        differences of ``clock()`` stamps that :meth:`tick` alone uses. The motors are stopped on
        the way out (the caller closes the drivers).
        """
        period = self.period
        deadline = time.monotonic()
        last_wake: float | None = None
        self._wall_timing = True  # periods from the wall clock, not from clock() stamps
        try:
            while not stop_event.is_set():
                wake = time.monotonic()
                if last_wake is not None:
                    with self._lock:
                        self.stats.add_period(wake - last_wake)
                last_wake = wake
                self.tick()
                work = self._link_work
                if work is not None:  # the link's bounded share of the tick
                    try:
                        work()
                    except Exception:  # never escapes the loop
                        log.exception("link work failed")
                deadline += period
                late = time.monotonic() - deadline
                if late > 0.0:
                    with self._lock:
                        self.stats.overruns += 1
                    deadline += (math.floor(late / period) + 1) * period
                stop_event.wait(max(0.0, deadline - time.monotonic()))
        finally:
            self._wall_timing = False
            with self._lock:
                self._stop_motors()

    def set_link_work(self, work: Callable[[], None] | None) -> None:
        """Have :meth:`run` call ``work()`` once per tick, after the tick: a link server's
        ``work_once`` in this process (at most one queued command, already decoded and
        validated) or the channel to a link process (``tool/channel.py``: at most four
        commands and one report, without waiting). Either way the network adds a bounded
        call to a tick. None detaches it."""
        self._link_work = work

    def tick(self, now: float | None = None, dt: float | None = None) -> ToolState:
        """One loop iteration at time ``now`` (default ``clock()``) with controller step
        ``dt`` (default: the time since the previous tick, or the nominal period).

        Reads the drivers, runs the filter and the mode's command, writes it, and returns the
        new snapshot. Never raises (an exception becomes a fault).
        """
        with self._lock:
            t_start = time.perf_counter()
            try:
                now = float(self.clock() if now is None else now)
                if self._last_now is not None:
                    elapsed = now - self._last_now
                    if elapsed > 0.0 and not self._wall_timing:
                        self.stats.add_period(elapsed)
                    if dt is None:
                        dt = elapsed
                if dt is None or not (math.isfinite(dt) and dt > 0.0):
                    dt = self.period
                dt = min(float(dt), 2.0 * self.period)
                self._last_now = now
                self._step(now, dt)
            except Exception as exc:
                log.exception("tool loop tick failed")
                self._set_fault(FaultKind.EXCEPTION, f"exception in control loop: "
                                f"{type(exc).__name__}: {exc}")
            try:
                self._snapshot = self._make_state(self._last_now or 0.0)
            except Exception as exc:  # telemetry must never take the loop down
                log.exception("building the state snapshot failed")
                self._set_fault(FaultKind.EXCEPTION, f"exception building state: {exc}")
            self.stats.add_compute(time.perf_counter() - t_start)
            return self._snapshot if self._snapshot is not None else self.state()

    # ---------------------------------------------------------------- internals --
    def _step(self, now: float, dt: float) -> None:
        if self._reboot_requested:
            self._reboot_requested = False
            self.motors.clear_errors()
            self.motors.enable_torque(True)

        # 1. motors
        try:
            ms = self.motors.read()
        except Exception as exc:
            self._motor_read_ok = False
            self._set_fault(FaultKind.MOTOR_READ, f"motor read failed: {type(exc).__name__}: {exc}")
            return
        self._motor_read_ok = True
        self._motor_state = ms
        q = np.asarray(ms.position, dtype=np.float64)
        if q.shape != (2,) or not np.isfinite(q).all():
            self._set_fault(FaultKind.MOTOR_READ, f"motor read gave invalid joints {q!r}")
            return

        # 2. IMU → filter (every sample since the last tick, in order)
        sensing = self._sensing
        sensing.read_imu(now)
        # 3. F/T (telemetry only: a failing F/T sensor never stops the tool)
        sensing.read_ft()
        self._energy.add(self._mode, dt)
        self._tilt = self._tool_tilt(q)

        # 4. safety
        if ms.has_hardware_error:
            self._set_fault(FaultKind.HARDWARE, f"motor hardware error: {ms.describe_errors()}")
            return
        outside, violation = self._envelope.check(q)
        if violation:
            self._set_fault(FaultKind.LIMIT, violation)
            return
        if self._mode in (Mode.LEVELING, Mode.FULL_ORIENTATION) and not sensing.imu_fresh:
            self._set_fault(FaultKind.IMU_STALE, sensing.stale_message(now))
            return

        # 5. the mode's command
        if self._mode is Mode.DISABLED:
            self._stop_motors()
            return
        if self._mode in (Mode.LEVELING, Mode.FULL_ORIENTATION):
            R = self.controller.tool_base_orientation(
                quaternion_to_matrix(self.filter.orientation))
            cmd = self._steering().command(R, q, sensing.gyro_corrected, dt)
        elif self._mode is Mode.PRIMITIVE:
            cmd = self._primitive_command(q, dt)
            if cmd is None:  # finished: back to DISABLED
                return
        else:
            cmd = self._follower.command(q, now)

        # 6. last checks, then write
        cmd = np.asarray(cmd, dtype=np.float64)
        if cmd.shape != (2,) or not np.isfinite(cmd).all():
            self._set_fault(FaultKind.COMMAND,
                            f"non-finite joint command {cmd!r} in mode {self._mode.name}")
            return
        cmd = np.clip(cmd, -self._vmax, self._vmax)
        if outside:  # recovering: only moves back towards the envelope are allowed
            violation = self._envelope.drives_further_out(q, cmd, outside)
            if violation:
                self._set_fault(FaultKind.LIMIT, f"{violation} and the {self._mode.name} command "
                                "drives it further out")
                return
        self.motors.set_velocity(cmd)
        self._command = cmd

    def _tool_tilt(self, q: NDArray[np.float64]) -> float:
        if not self.filter.initialized:
            return math.nan
        R = self.controller.tool_base_orientation(quaternion_to_matrix(self.filter.orientation))
        return float(tilt_from_vertical(R @ up_vector(q)))

    def _primitive_command(self, q: NDArray[np.float64], dt: float) -> NDArray[np.float64] | None:
        prim = self._primitive
        assert prim is not None
        prim.sense(self._sensing.ft_fresh)
        cmd = prim.step(q, dt)
        self._primitive_status = prim.status()
        if prim.done:
            self._primitive = None
            self._enter(Mode.DISABLED)
            return None
        return cmd

    def prevalidate_trajectory(self, trajectory: JointTrajectory) -> JointTrajectory:
        """The checks of :meth:`follow_trajectory` that do not depend on the wrist's state
        (joint names, waypoint limits, the interpolated spline's limits), without the lock.

        The link server runs this in its own thread (in ``articutool tool``, its own
        process), so the loop, which runs the queued :meth:`follow_trajectory`, only checks
        the start against the present joints (cost independent of the trajectory's length:
        a 1 MB trajectory takes up to 190 ms to validate in full). Raises TrajectoryError
        (or TypeError) with the reason; returns the trajectory in the wrist's joint order,
        marked as checked by this runtime.
        """
        return self._follower.prevalidate(trajectory)

    def adopt_prevalidated(self, trajectory: JointTrajectory) -> JointTrajectory:
        """``trajectory`` as :meth:`prevalidate_trajectory` returned it in the tool's link
        process (the same spec, another process: it arrives as a new object), marked so that
        :meth:`follow_trajectory` only checks its start. Its type, joint order and length are
        checked again here (cheap); TrajectoryError otherwise."""
        if not isinstance(trajectory, JointTrajectory):
            raise TypeError(f"expected a JointTrajectory; got {type(trajectory).__name__}")
        if tuple(trajectory.joint_names) != self.joint_names:
            raise TrajectoryError(f"joint_names must be {list(self.joint_names)} in this "
                                  f"order; got {list(trajectory.joint_names)}")
        if float(trajectory.times[-1]) > self._follower.max_duration:
            raise TrajectoryError(f"a trajectory ends at most {self._follower.max_duration:g} "
                                  "s after its start (spec.primitives.max_duration_s)")
        return self._follower.adopt(trajectory)

    # -- modes and faults --
    def _enter(self, mode: Mode) -> None:
        """Switch mode (lock held): abort a running primitive, drop a trajectory, and stop
        the motors when the new mode is DISABLED."""
        if self._primitive is not None and mode is not Mode.PRIMITIVE:
            self._abort_primitive(f"{ABORTED_BY_MODE_CHANGE}{mode.name}")
        if mode is not Mode.TRAJECTORY:
            self._follower.drop()
        if mode is Mode.DISABLED:
            self._stop_motors()
        if mode is Mode.LEVELING and self._mode is not Mode.LEVELING:
            self.controller.reset()
        self._mode = mode

    def _steering(self) -> Leveling:
        """The orientation mode's part (LEVELING's, or FULL_ORIENTATION's)."""
        return self._attitude if self._mode is Mode.FULL_ORIENTATION else self._leveling

    def _abort_primitive(self, message: str) -> None:
        prim = self._primitive
        if prim is None:
            return
        self._primitive = None
        prim.cancel()
        self._primitive_status = replace(prim.status(), done=True, success=False, message=message)
        self._stop_motors()

    def _stop_motors(self) -> None:
        """Stop the motors. The command reads zero only once the stop is confirmed; a failed
        stop is a fault (the motors may run on until their bus watchdog stops them)."""
        try:
            self.motors.stop()
        except Exception as exc:
            message = f"motor stop failed: {type(exc).__name__}: {exc}"
            self._stop_failures += 1
            if self._stop_ok and self._fault:  # else _set_fault logs it as the fault
                log.error("%s", message)
            self._stop_ok = False
            if not self._in_stop_fault:  # _set_fault stops again: no recursion
                self._in_stop_fault = True
                try:
                    self._set_fault(FaultKind.MOTOR_STOP, message)
                finally:
                    self._in_stop_fault = False
            return
        self._stop_ok = True
        self._command = np.zeros(2)

    def _set_fault(self, kind: FaultKind, message: str) -> None:
        """Safe state: stop, DISABLED, keep the first cause."""
        if not self._fault:
            self._faults_total += 1
            self._fault, self._fault_kind = message, kind
            log.error("tool fault: %s", message)
        try:
            self._abort_primitive(f"aborted by fault: {message}")
        except Exception:  # a broken primitive must not keep the motors running
            log.exception("aborting the primitive failed")
            self._primitive = None
        self._follower.drop()
        self._mode = Mode.DISABLED
        self._stop_motors()

    def _clear_fault(self) -> None:
        if self._fault_kind is FaultKind.LIMIT and self._motor_state is not None:
            q = np.asarray(self._motor_state.position, dtype=np.float64)
            self._envelope.arm_recovery(q)
        self._fault = ""
        self._fault_kind = None

    def _fault_cause(self) -> str:
        """Why the current fault cannot be cleared yet; empty when its cause is gone."""
        kind = self._fault_kind
        ms = self._motor_state
        if kind is FaultKind.MOTOR_READ and not self._motor_read_ok:
            return "the motors do not answer"
        if kind is FaultKind.HARDWARE and ms is not None and ms.has_hardware_error:
            return f"motor hardware error: {ms.describe_errors()}"
        if kind is FaultKind.IMU_STALE and not self._sensing.imu_fresh:
            return "IMU data still stale"
        if kind is FaultKind.MOTOR_STOP and not self._stop_ok:
            return "the motors do not confirm a stop"
        return ""

    # -- telemetry --
    def _make_state(self, now: float) -> ToolState:
        return build_state(
            now, mode=self._mode, fault=self._fault, joint_names=self.joint_names,
            motor_state=self._motor_state, sensing=self._sensing, filt=self.filter,
            tilt=self._tilt, command=self._command, stats=self.stats,
            faults_total=self._faults_total, stop_failures=self._stop_failures,
            energy=self._energy, leveling=self._steering(), follower=self._follower,
            limits=self._limits)
