"""The runtime's telemetry: loop statistics, the energy estimate and the state snapshot
(thesis §3.1, §3.2).

:class:`LoopStats` keeps the loop's timing (period mean and jitter by Welford's method, max,
percentiles from a fixed histogram, overruns, a tick's compute time). :class:`EnergyMeter`
integrates the spec's power budget per mode (idle in DISABLED, leveling in LEVELING, peak —
an upper bound — in PRIMITIVE and TRAJECTORY): the bank is assumed to hold
``battery_start_pct`` at start, since the 12 V supply is regulated and the voltage alone says
little about the charge. :func:`build_state` is the pure assembly of one
:class:`~articutool.tool.api.ToolState` (with its ``extra`` fields) from the parts
:class:`~articutool.tool.runtime.ToolRuntime` composes.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from articutool.spec import Spec
from articutool.tool.api import Mode, ToolState
from articutool.tool.drivers.base import MotorState
from articutool.tool.filter import ComplementaryFilter
from articutool.tool.following import TrajectoryFollower
from articutool.tool.modes import Leveling
from articutool.tool.sensing import Sensing

__all__ = ["LIMIT_KEYS", "EnergyMeter", "LoopStats", "build_state", "reported_limits"]

#: The ``extra`` keys that carry the tool's joint limits (its spec's ``wrist.limits``, rad),
#: [pitch, roll] × [low, high]: a client learns the limits of the tool it is connected to.
LIMIT_KEYS = (("pitch_limit_low", "pitch_limit_high"), ("roll_limit_low", "roll_limit_high"))


class LoopStats:
    """Loop timing: period mean and standard deviation (jitter, Welford), max, percentiles,
    overruns, and the compute time of a tick (mean, max).

    Percentiles come from a histogram of 0.1 ms bins up to 1 s (periods beyond it count in
    the last bin): constant memory and an O(1) update, so the loop can keep it for as long
    as it runs. A percentile is the upper edge of its bin (at most 0.1 ms high), capped at
    the maximum seen.
    """

    BIN_S = 1e-4
    BINS = 10_000

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget all samples."""
        self.count = 0
        self.mean = math.nan
        self._m2 = 0.0
        self.max = math.nan
        self.overruns = 0
        self.ticks = 0
        self.compute_mean = math.nan
        self.compute_max = math.nan
        self.hist = np.zeros(self.BINS, dtype=np.int64)

    def add_period(self, p: float) -> None:
        """Record one measured period (s)."""
        self.hist[min(self.BINS - 1, max(0, int(p / self.BIN_S)))] += 1
        self.count += 1
        if self.count == 1:
            self.mean, self._m2, self.max = p, 0.0, p
            return
        d = p - self.mean
        self.mean += d / self.count
        self._m2 += d * (p - self.mean)
        self.max = max(self.max, p)

    def add_compute(self, c: float) -> None:
        """Record the compute time (s) of one tick."""
        self.ticks += 1
        if self.ticks == 1:
            self.compute_mean = self.compute_max = c
            return
        self.compute_mean += (c - self.compute_mean) / self.ticks
        self.compute_max = max(self.compute_max, c)

    def percentiles(self, *qs: float) -> tuple[float, ...]:
        """The ``qs``-th percentiles (0–100) of the periods (s); NaN before the first."""
        if self.count == 0:
            return tuple(math.nan for _ in qs)
        cum = np.cumsum(self.hist)
        out = []
        for q in qs:
            i = int(np.searchsorted(cum, max(1, math.ceil(q / 100.0 * self.count))))
            out.append(min((i + 1) * self.BIN_S, self.max))
        return tuple(out)

    def count_over(self, limit: float) -> int:
        """How many periods were ``limit`` seconds or longer (to the bin, so it may also count
        periods up to 0.1 ms shorter: it never misses one)."""
        return int(self.hist[min(self.BINS - 1, int(limit / self.BIN_S)):].sum())

    @property
    def jitter(self) -> float:
        """Standard deviation of the period (s); NaN with fewer than two periods."""
        return math.sqrt(self._m2 / (self.count - 1)) if self.count > 1 else math.nan


class EnergyMeter:
    """Energy used since start at the spec's power per mode (thesis §3.1)."""

    def __init__(self, spec: Spec, battery_start_pct: float) -> None:
        if not (math.isfinite(battery_start_pct) and 0.0 <= battery_start_pct <= 100.0):
            raise ValueError(f"battery_start_pct must be in [0, 100]; got {battery_start_pct}")
        p = spec.power
        self.battery_wh = p.battery_wh
        self.start_wh = p.battery_wh * battery_start_pct / 100.0
        self.power_w = {
            Mode.DISABLED: p.idle_w,
            Mode.LEVELING: p.leveling_w,
            Mode.FULL_ORIENTATION: p.leveling_w,
            Mode.PRIMITIVE: p.peak_w,
            Mode.TRAJECTORY: p.peak_w,
        }
        self.used_wh = 0.0

    def add(self, mode: Mode, dt: float) -> None:
        """Account ``dt`` seconds in ``mode``."""
        self.used_wh += self.power_w[mode] * dt / 3600.0


def build_state(
    now: float,
    *,
    mode: Mode,
    fault: str,
    joint_names: tuple[str, str],
    motor_state: MotorState | None,
    sensing: Sensing,
    filt: ComplementaryFilter,
    tilt: float,
    command: NDArray[np.float64],
    stats: LoopStats,
    faults_total: int,
    stop_failures: int,
    energy: EnergyMeter,
    leveling: Leveling,
    follower: TrajectoryFollower,
    limits: NDArray[np.float64],
) -> ToolState:
    """The snapshot at ``now``; ``extra`` carries what ``ToolState`` has no field for."""
    # Indexing, not tuple(generator): the snapshot is built every tick (50 Hz).
    ms = motor_state
    nan2, nan3 = (math.nan, math.nan), (math.nan, math.nan, math.nan)
    p = nan2 if ms is None else ms.position
    v = nan2 if ms is None else ms.velocity
    pos = (float(p[0]), float(p[1]))
    vel = (float(v[0]), float(v[1]))
    s = sensing.last_imu
    a = nan3 if s is None else s.accel
    g = nan3 if s is None else sensing.gyro_corrected
    o = filt.orientation
    acc = (float(a[0]), float(a[1]), float(a[2]))
    gyr = (float(g[0]), float(g[1]), float(g[2]))
    quat = (float(o[0]), float(o[1]), float(o[2]), float(o[3]))
    volts = math.nan if ms is None else float(ms.input_voltage)
    used = energy.used_wh
    left = max(0.0, energy.start_wh - used)
    power = energy.power_w[mode]
    offsets = leveling.offsets_deg
    p50, p99 = stats.percentiles(50.0, 99.0)
    period = follower.period
    extra: dict[str, float] = {
        "tilt_deg": math.degrees(tilt),
        "imu_age_s": now - sensing.last_imu_stamp,
        "imu_stale": 0.0 if sensing.imu_fresh else 1.0,
        "imu_bad": float(sensing.imu_bad),
        "imu_filter_resets": float(sensing.imu_resets),
        "steady_state": 1.0 if filt.steady_state else 0.0,
        "command_pitch": float(command[0]),
        "command_roll": float(command[1]),
        "singularity": abs(math.cos(pos[1])) if ms is not None else math.nan,
        "loop_period_max": stats.max,
        "loop_period_p50": p50,
        "loop_period_p99": p99,
        "loop_periods_over_2x": float(stats.count_over(2.0 * period)),
        "loop_period_count": float(stats.count),
        "tick_compute_mean_s": stats.compute_mean,
        "tick_compute_max_s": stats.compute_max,
        "faults_total": float(faults_total),
        "motor_stop_failures": float(stop_failures),
        "battery_used_wh": used,
        "battery_remaining_pct": 100.0 * left / energy.battery_wh,
        "battery_runtime_h": left / power,
        "power_w_est": power,
        "pitch_offset_deg": offsets[0],
        "roll_offset_deg": offsets[1],
    }
    for keys, bounds in zip(LIMIT_KEYS, limits, strict=True):
        extra[keys[0]], extra[keys[1]] = float(bounds[0]), float(bounds[1])
    if ms is not None:
        extra["motor_temperature"] = float(ms.temperature)
    if mode in (Mode.LEVELING, Mode.FULL_ORIENTATION):
        stall = leveling.stall_target
        extra["leveling_stalled"] = 0.0 if stall is None else 1.0
        if stall is not None:
            extra["leveling_target_pitch"], extra["leveling_target_roll"] = stall
    if mode is Mode.TRAJECTORY:
        extra["trajectory_progress_pct"] = follower.progress
        extra["trajectory_error"] = follower.error
    if sensing.ft_last is not None:
        for k, v in zip(("ft_fx", "ft_fy", "ft_fz", "ft_tx", "ft_ty", "ft_tz"),
                        sensing.ft_last, strict=True):
            extra[k] = v
    if sensing.ft_errors:
        extra["ft_errors"] = float(sensing.ft_errors)
    return ToolState(
        stamp=now,
        mode=mode,
        joint_names=joint_names,
        position=pos,
        velocity=vel,
        orientation_wxyz=quat,
        angular_velocity=gyr,
        linear_acceleration=acc,
        fault=fault,
        battery_voltage=volts,
        loop_period_mean=stats.mean,
        loop_jitter=stats.jitter,
        loop_overruns=stats.overruns,
        extra=extra,
    )


def reported_limits(state: ToolState | None) -> NDArray[np.float64] | None:
    """The joint limits (rad, [pitch, roll] × [low, high]) a tool reports in its state's
    ``extra`` (:data:`LIMIT_KEYS`), or None when it reports none (no state yet, or a tool
    that does not send them)."""
    if state is None:
        return None
    try:
        out = np.array([[state.extra[lo], state.extra[hi]] for lo, hi in LIMIT_KEYS],
                       dtype=np.float64)
    except KeyError:
        return None
    return out if np.all(np.isfinite(out)) and np.all(out[:, 0] <= out[:, 1]) else None
