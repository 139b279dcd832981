"""Execute an arm transport in simulation while the onboard loop levels the utensil.

The arm follows its time-parameterised trajectory kinematically (the Jaco's own joint
controllers track well at transport speeds); the tool base's orientation, angular velocity and
linear acceleration come from the arm model and drive the simulated wrist
(``articutool.tool.drivers.sim.SimWrist``). The wrist's onboard software — the real
``ToolRuntime`` with its complementary filter and leveling controller (Alg. 1), fed by the
simulated IMU with noise and gyro bias — keeps the utensil level on its own: nothing from the
plan reaches the tool, which is the decoupled architecture of the thesis (§4.3.2). The
ground-truth tilt of the utensil is recorded at every loop tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from articutool.api_types import ArmKinematics
from articutool.spec import Spec
from articutool.tool.api import Mode
from articutool.tool.drivers.sim import SimWrist
from articutool.tool.kinematics import tilt_from_vertical, up_vector
from articutool.tool.runtime import ToolRuntime
from articutool.trajectory import JointTrajectory

__all__ = ["TransportSimResult", "simulate_transport"]

_ACCEL_H = 2e-3  # s, central-difference step for the tool base's linear acceleration


@dataclass(frozen=True)
class TransportSimResult:
    """Ground truth of one simulated transport (times from the start of the arm motion)."""

    times: NDArray[np.float64]  # (N,) s; negative during the settling phase
    tilt_deg: NDArray[np.float64]  # (N,) utensil up vector vs world z
    wrist_q: NDArray[np.float64]  # (N, 2) [pitch, roll]
    base_tilt_deg: NDArray[np.float64]  # (N,) how far the tool base's rest-up axis is tilted
    duration_s: float
    faults: tuple[str, ...]

    def _moving(self) -> NDArray[np.bool_]:
        return (self.times >= 0.0) & (self.times <= self.duration_s)

    @property
    def max_tilt_error_deg(self) -> float:
        """Largest utensil tilt while the arm moves."""
        return float(self.tilt_deg[self._moving()].max())

    @property
    def rms_tilt_error_deg(self) -> float:
        """RMS utensil tilt while the arm moves."""
        return float(np.sqrt(np.mean(self.tilt_deg[self._moving()] ** 2)))

    @property
    def final_tilt_error_deg(self) -> float:
        """Utensil tilt at the end of the record (after the hold)."""
        return float(self.tilt_deg[-1])


def _base_motion(arm: ArmKinematics, traj: JointTrajectory, t0: float):
    """``t -> (R_world←F0, ω_world, a_world)`` along ``traj`` started at sim time ``t0``."""

    def position(ts: NDArray[np.float64]) -> NDArray[np.float64]:
        q, _ = traj.sample(ts)
        return np.stack([arm.tool_base_pose(qi)[:3, 3] for qi in q])

    def motion(t: float):
        tau = np.array([t - t0])
        q, qd = traj.sample(tau)
        moving = 0.0 <= tau[0] <= traj.duration
        R, w = arm.tool_base_kinematics(q, qd if moving else np.zeros_like(qd))
        a = np.zeros(3)
        if moving:
            p = position(tau[0] + np.array([-_ACCEL_H, 0.0, _ACCEL_H]))
            a = (p[0] - 2 * p[1] + p[2]) / _ACCEL_H**2
        return R[0], w[0], a

    return motion


def simulate_transport(
    traj: JointTrajectory,
    arm: ArmKinematics,
    spec: Spec,
    *,
    settle_s: float = 2.0,
    hold_s: float = 1.0,
    gyro_bias_dps: tuple[float, float, float] = (1.0, -1.5, 0.5),
    noise: bool = True,
    seed: int = 0,
) -> TransportSimResult:
    """Run the transport with the wrist LEVELING; returns the utensil's ground-truth tilt.

    ``traj`` is the arm trajectory (names as ``spec.arm``). The wrist starts at zero; during
    ``settle_s`` the arm holds its start so the filter converges and the loop levels the tool
    (as the thesis' post-acquisition leveling does), then the arm moves, then holds ``hold_s``.
    """
    traj = traj.reordered(spec.arm.joint_names)
    if not (settle_s >= 0.5 and hold_s >= 0.0):
        raise ValueError("settle_s must be >= 0.5 s and hold_s >= 0 s")
    sim = SimWrist(spec, gyro_bias=np.radians(gyro_bias_dps), noise=noise, seed=seed)
    sim.set_base_motion(_base_motion(arm, traj, settle_s))
    runtime = ToolRuntime(spec, sim.motor_driver(), sim.imu_driver(), clock=sim.clock)
    period = spec.wrist.period
    n = round((settle_s + traj.duration + hold_s) / period)
    times = np.empty(n)
    tilt = np.empty(n)
    wrist = np.empty((n, 2))
    base_tilt = np.empty(n)
    faults: list[str] = []
    rigid_up = up_vector(np.zeros(2))  # the utensil's up in F0 with the wrist at zero
    with runtime:
        for k in range(n):
            sim.step(period)
            state = runtime.tick(now=sim.time, dt=period)
            if state.fault and (not faults or faults[-1] != state.fault):
                faults.append(state.fault)
            if state.mode is Mode.DISABLED and not state.fault and k * period >= 0.1:
                ok, msg = runtime.set_mode(Mode.LEVELING)
                if not ok and (not faults or faults[-1] != msg):
                    faults.append(msg)
            times[k] = sim.time - settle_s
            tilt[k] = np.degrees(sim.tilt_error())
            wrist[k] = sim.q
            R, _, _ = sim.base_state()
            base_tilt[k] = np.degrees(tilt_from_vertical(R @ rigid_up))
    return TransportSimResult(times, tilt, wrist, base_tilt, traj.duration, tuple(faults))
