"""The feeding world: MuJoCo physics with the Articutool's own onboard software in the loop.

:class:`FeedingWorld` builds the MJCF from the spec, the scene and a food
(:mod:`articutool.sim.mjcf`), lets the food settle, then runs the unchanged
:class:`~articutool.tool.runtime.ToolRuntime` on MuJoCo-backed drivers
(:mod:`articutool.sim.mj_drivers`) at ``spec.wrist.loop_rate_hz`` in lockstep with the physics:
each physics step applies the arm servos' references and the wrist motors' torques, steps,
then emits IMU and F/T samples at their rates; every loop period the runtime ticks on the
simulation clock. Commands reach the tool through ``world.tool``, the same ``ToolAPI`` the
link serves. For speed the steps between two ticks run as one batch with the
per-step Python cut to what depends on the step, and a settled pile is restored rather than
settled again; both are bit-identical to stepping one at a time and settling afresh
(``tests/test_sim_speed.py``; where the time goes: docs/simulation.md, *Speed*).

One stepping loop — arm servos, the wrist's velocity loop, sensors, the tool's tick — and the
arm-motion API around it; the food ledger and load placement live apart.

The arm follows a :class:`~articutool.trajectory.JointTrajectory` with joint servos (PD with
velocity feed-forward, torque-limited by the spec's efforts), so contacts see the real
velocity of the utensil — never a teleported body. The tracking error is recorded.

The food ledger (:class:`~articutool.sim.ledger.FoodLedger`, rules in
:mod:`articutool.sim.accounting`) runs every loop period: the mass on the utensil, in its
container, on the table, on critical places, in the air, eaten; every spill with its time,
mass and place. Food entering the scene's ``mouth`` region is eaten (removed). Placing a load
by hand: :mod:`articutool.sim.loading`.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.arm.scene import Scene
from articutool.sim import accounting as acc
from articutool.sim.ledger import FoodLedger
from articutool.sim.loading import (
    DEPOSIT_CLEARANCE_M,
    deposit_spot,
    dish_surface_height,
    max_load_g,
    pour_lattice,
)
from articutool.sim.mj_drivers import MjFTDriver, MjImuDriver, MjMotorDriver
from articutool.sim.mjcf import (
    FT_SITE,
    IMU_SITE,
    WorldLayout,
    build_mjcf,
    tip_site_name,
)
from articutool.sim.params import Granular, Liquid, PhysicsParams, Strands
from articutool.spec import Spec, load_spec
from articutool.tool.drivers.motor_model import MotorPlant
from articutool.tool.runtime import ToolRuntime
from articutool.trajectory import JointTrajectory

__all__ = ["FeedingWorld", "FoodReport", "PhysicsResetError", "SettleCache",
           "capacity_bound_reason", "smooth_joint_motion", "utensil_capacity_bound_g"]

# MuJoCo's warnings on which mj_step resets mjData to the model's defaults (its "simulation is
# unstable" reset: NaN, Inf or huge qpos/qvel/qacc). Everything after is not the run's physics.
_RESET_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                   mujoco.mjtWarning.mjWARN_BADQACC)


# Pieces in a placed load's supply per gram of the load (place_load deposits until the utensil
# holds the load; the rest stays parked). A numerical choice: at the capacity load a third of
# the deposited pieces rolled off the heap in trials (seeds 0-4), so twice the load suffices.
SUPPLY_FACTOR = 2.0


def utensil_capacity_bound_g(spec: Spec, params: PhysicsParams, food: str,
                             utensil: str | None = None) -> float:
    """The most ``utensil`` (default: the food's) can hold of ``food`` (g): a liquid fills
    its dish level to the rim, pieces the dish and a heap at their angle of repose
    (:func:`articutool.sim.loading.max_load_g`)."""
    fp = params.food(food)
    u = spec.utensil(utensil or fp.utensil)
    return max_load_g(u, fp.kind, fp.density,
                      fp.angle_of_repose_deg if isinstance(fp, Granular) else None)


def load_supply_g(params: PhysicsParams, food: str | None,
                  load_g: float | None) -> float | None:
    """What the world places to leave ``load_g`` of ``food`` on the utensil. A hand takes
    pieces from a supply until the utensil holds the load: some roll off on the way
    (:meth:`FeedingWorld.place_load`), so a granular supply holds more than the load."""
    if load_g is not None and food is not None and isinstance(params.food(food), Granular):
        return SUPPLY_FACTOR * load_g
    return load_g


def capacity_bound_reason(fp: Granular | Liquid | Strands) -> str:
    """Why :func:`utensil_capacity_bound_g` is the bound, in words."""
    if isinstance(fp, Liquid):
        return "its dish filled level to the rim: a liquid without surface tension holds no more"
    return (f"its dish and a heap at the pieces' {fp.angle_of_repose_deg:g}° angle of repose, "
            "as solid kernel")


class PhysicsResetError(RuntimeError):
    """MuJoCo reset the simulation after a numerical instability: the arm, the wrist and the
    food jumped back to the model's defaults, so the run's outcome is meaningless: it stops
    here and is never counted."""

class SettleCache:
    """Settled worlds by (model, start state), restored instead of settled again: the
    same model and start state settle to the same state, so a copy of every byte of
    ``mjData`` (sleep state, contacts and the solver's warm start included) and the world's
    own servo state is the state a fresh settle makes, to the bit
    (``tests/test_sim_speed.py``). Whoever runs many worlds owns one (the experiments'
    runner, one per worker process: an experiment's conditions share a repeat's seed, so
    they share its settled pile); a world built without one settles afresh.

    It keeps the ``keep`` most recently used states (one is a full ``mjData``)."""

    def __init__(self, keep: int = 4) -> None:
        if keep < 1:
            raise ValueError(f"keep must be >= 1; got {keep}")
        self.keep = keep
        self._states: dict[str, tuple[mujoco.MjData, NDArray[np.float64], float, int]] = {}

    def __len__(self) -> int:
        return len(self._states)

    def take(self, key: str) -> tuple[mujoco.MjData, NDArray[np.float64], float, int] | None:
        """The state settled under ``key`` (removed until :meth:`put` back), or None."""
        return self._states.pop(key, None)

    def put(self, key: str,
            state: tuple[mujoco.MjData, NDArray[np.float64], float, int]) -> None:
        """Keep ``state`` under ``key`` as the most recently used; forget the oldest beyond
        ``keep``."""
        self._states.pop(key, None)
        self._states[key] = state
        while len(self._states) > self.keep:
            self._states.pop(next(iter(self._states)))

_ZUP = np.array([0.0, 0.0, 1.0])


def _model_bytes(m: mujoco.MjModel) -> bytes:
    """The compiled model as MuJoCo saves it (every number and name): its identity."""
    buf = np.empty(mujoco.mj_sizeModel(m), dtype=np.uint8)
    mujoco.mj_saveModel(m, None, buf)
    return buf.tobytes()


@dataclass
class FoodReport:
    """Where the food is (grams) at time ``t``, and every spill so far."""

    t: float
    food: str | None
    utensil: str
    on_utensil_g: float
    in_bowl_g: float  # back in its container (bowl or plate)
    table_g: float  # non-critical spill
    critical_g: float  # on the user, wheelchair or floor
    airborne_g: float
    eaten_g: float
    total_g: float
    spills: list[acc.SpillEvent] = field(default_factory=list)
    ft_mass_g: float | None = None  # as the F/T sensor measures it (at rest, level)
    realtime_factor: float = math.nan
    arm_tracking_error_rad: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (spills as a list of dicts)."""
        d = asdict(self)
        d["spills"] = [asdict(s) for s in self.spills]
        return d


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


class FeedingWorld:
    """One simulated meal scene (see module doc).

    Args:
        food: a food of ``physics.toml`` (``None``: no food).
        utensil: which utensil the tool carries (default: the food's utensil).
        spec, scene, params: hardware spec, scene and physics parameters (packaged defaults).
        seed: food placement, sensor noise and gyro bias; same seed, same result.
        q_arm: the arm's start configuration (default: the spec's ``Resting``).
        q_wrist: the wrist's start angles [pitch, roll] (rad).
        noise: sensor noise on (IMU, F/T); the gyro bias is on either way unless given.
        gyro_bias: rad/s (3,); default drawn from ±1 °/s per axis with the seed.
        settle: let the food settle for ``params.world.settle_s`` before the tool starts.
        load_g: instead of filling the food's container, hold this many grams of it ready to
            be placed on the utensil with :meth:`place_load` (the thesis' Exp. 2b/2c protocol:
            a tared utensil loaded by hand).
        mouth: food entering the scene's ``mouth`` region is eaten (a bite); ``False`` for
            protocols in which nobody eats and the experimenter weighs the utensil at the
            goal (Exp. 2b, 2c).
        settle_cache: restores the settled state of an earlier world with the same model
            and start state instead of settling again (bit-identical; :class:`SettleCache`);
            ``None`` settles afresh.
    """

    def __init__(
        self,
        food: str | None = "pecans",
        utensil: str | None = None,
        *,
        spec: Spec | None = None,
        scene: Scene | None = None,
        params: PhysicsParams | None = None,
        seed: int = 0,
        q_arm: ArrayLike | None = None,
        q_wrist: ArrayLike = (0.0, 0.0),
        noise: bool = True,
        gyro_bias: ArrayLike | None = None,
        settle: bool = True,
        load_g: float | None = None,
        mouth: bool = True,
        settle_cache: SettleCache | None = None,
    ) -> None:
        self.spec = spec if spec is not None else load_spec()
        self.scene = scene if scene is not None else Scene.load()
        self.params = params if params is not None else PhysicsParams.load()
        if food is not None:
            self.params.food(food)  # unknown food → PhysicsError naming the allowed ones
        self.food = food
        self.utensil = utensil or (self.params.food(food).utensil if food else "spoon")
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
        self.seed = int(seed)
        self._settle_cache = settle_cache
        if load_g is not None and not (math.isfinite(load_g) and load_g > 0):
            raise ValueError(f"load_g must be a finite mass > 0 g; got {load_g}")
        if load_g is not None and food is None:
            raise ValueError("load_g needs a food")
        if load_g is not None and load_g > (most := self.capacity_bound_g(food or "")):
            why = capacity_bound_reason(self.params.food(food or ""))
            raise ValueError(f"load_g must be in (0, {most:.2f}] g: the most the "
                             f"{self.utensil} can hold of {food} ({why}); got {load_g:g}")
        self.load_g = load_g
        self.layout: WorldLayout = build_mjcf(self.spec, self.scene, self.params, self.utensil,
                                              food, self.seed,
                                              load_supply_g(self.params, food, load_g))
        self.model = self.layout.spec.compile()
        self.data = mujoco.MjData(self.model)
        m, d = self.model, self.data
        rng = np.random.default_rng(self.seed + 1_000_003)

        # --- indices
        self._arm_q = np.array([m.joint(n).qposadr[0] for n in self.layout.arm_joints])
        self._arm_v = np.array([m.joint(n).dofadr[0] for n in self.layout.arm_joints])
        self._wr_q = np.array([m.joint(n).qposadr[0] for n in self.layout.wrist_joints])
        self._wr_v = np.array([m.joint(n).dofadr[0] for n in self.layout.wrist_joints])
        self._act_pos = np.array([m.actuator(f"{n}/pos").id for n in self.layout.arm_joints])
        self._act_vel = np.array([m.actuator(f"{n}/vel").id for n in self.layout.arm_joints])
        self._act_wr = np.array([m.actuator(f"{n}/motor").id
                                 for n in self.layout.wrist_joints])
        self.wrist_range = np.array([m.jnt_range[m.joint(n).id]
                                     for n in self.layout.wrist_joints])
        self._s_acc = m.sensor("imu_accel").adr[0]
        self._s_gyro = m.sensor("imu_gyro").adr[0]
        self._s_force = m.sensor("ft_force").adr[0]
        self._s_torque = m.sensor("ft_torque").adr[0]
        self._tip_site = m.site(tip_site_name(self.utensil)).id
        self._ft_site = m.site(FT_SITE).id
        self._imu_site = m.site(IMU_SITE).id
        wm = self.params.wrist_motor
        self._kv, self._ki = wm.kv, wm.ki
        self._tq = self.spec.motors.stall_torque_nm
        self._vel_int = np.zeros(2)
        self.ledger = FoodLedger(m, d, self.layout, self.scene, self.params.world.spill_dwell_s,
                                 self.spec.wrist.period, mouth=mouth)

        # --- timing
        self.dt = float(m.opt.timestep)
        period = self.spec.wrist.period
        self._steps_per_tick = round(period / self.dt)
        if abs(self._steps_per_tick * self.dt - period) > 1e-9:
            raise ValueError(f"world.timestep {self.dt} s must divide the loop period "
                             f"{period} s")
        self._imu_period = 1.0 / self.spec.imu.rate_hz
        self._ft_period = 1.0 / self.spec.ft.rate_hz
        self._step_count = 0
        self._resets = 0  # MuJoCo's reset warnings seen so far (see PhysicsResetError)
        # Called after every tool tick with the world (recorders, loggers); not timed.
        self.on_tick: list[Callable[[FeedingWorld], None]] = []
        self._cpu = 0.0
        self._sim_stepped = 0.0

        # --- start state
        q0 = np.asarray(self.spec.arm.configuration("Resting") if q_arm is None else q_arm,
                        dtype=float)
        if q0.shape != (6,) or not np.isfinite(q0).all():
            raise ValueError(f"q_arm must be 6 finite joint angles; got {q_arm!r}")
        lo, hi = self.spec.arm.lower, self.spec.arm.upper
        bad = np.flatnonzero((q0 < lo) | (q0 > hi))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"q_arm[{i}] = {q0[i]:.4g} rad is outside the joint's range "
                             f"[{lo[i]:.4g}, {hi[i]:.4g}]")
        qw = np.asarray(q_wrist, dtype=float)
        if qw.shape != (2,) or not np.isfinite(qw).all():
            raise ValueError(f"q_wrist must be 2 finite angles [pitch, roll]; got {q_wrist!r}")
        d.qpos[self._arm_q] = q0
        d.qpos[self._wr_q] = qw
        self._arm_ref = q0.copy()
        self._arm_ref_v = np.zeros(6)
        self._arm_traj: JointTrajectory | None = None
        self._arm_t0 = 0.0
        self.arm_tracking_error = 0.0
        mujoco.mj_forward(m, d)

        # --- the tool and its drivers
        bias = (rng.uniform(-1.0, 1.0, 3) * math.radians(1.0) if gyro_bias is None
                else np.asarray(gyro_bias, dtype=float))
        plant = MotorPlant(position=lambda: self.wrist_q, velocity=lambda: self.wrist_qd,
                           input_voltage=lambda: self.spec.motors.supply_v,
                           temperature=lambda: 35.0, stamp=lambda: self.time)
        self.motors = MjMotorDriver(self.spec, plant, self.wrist_range)
        self.imu = MjImuDriver(self.spec, bias, noise, rng)
        self.ft = MjFTDriver(self.spec, noise, rng)
        self.tool = ToolRuntime(self.spec, self.motors, self.imu, self.ft, clock=self.clock)
        # The servos (and the food, if any) settle with the wrist held; then the tool starts.
        self._hold_wrist = True
        self._settle(self.params.world.settle_s if settle and food is not None else 0.2)
        self._hold_wrist = False
        self._next_imu = self.time
        self._next_ft = self.time
        self.tool.open()
        self.run(0.2)
        self.tare_ft()
        self._classify()

    def _settle(self, seconds: float) -> None:
        """Run ``seconds`` with the tool off, or, with a :class:`SettleCache`, restore the
        state that run left last time (bit-identical to settling again)."""
        m, d = self.model, self.data
        cache = self._settle_cache
        if cache is None:
            self.run(seconds, tick=False)
            return
        h = hashlib.sha256(_model_bytes(m))
        for a in (d.qpos, d.qvel, m.tree_sleep_policy,
                  np.array([seconds, self._kv, self._ki, self._tq])):
            h.update(np.ascontiguousarray(a).tobytes())
        key = h.hexdigest()
        hit = cache.take(key)
        if hit is None:
            self.run(seconds, tick=False)
            snap = mujoco.MjData(m)
            mujoco.mj_copyData(snap, m, d)
            hit = (snap, self._vel_int.copy(), self.arm_tracking_error, self._step_count)
        else:
            snap, vel_int, err, n = hit
            mujoco.mj_copyData(d, m, snap)
            self._vel_int, self.arm_tracking_error, self._step_count = vel_int.copy(), err, n
        cache.put(key, hit)

    # ----------------------------------------------------------------- accessors --
    @property
    def time(self) -> float:
        """Simulation time (s)."""
        return float(self.data.time)

    def clock(self) -> float:
        """The simulation clock (the tool runtime's clock)."""
        return float(self.data.time)

    @property
    def wrist_q(self) -> NDArray[np.float64]:
        """Wrist joint angles [pitch, roll] (rad), ground truth."""
        return self.data.qpos[self._wr_q].copy()

    @property
    def wrist_qd(self) -> NDArray[np.float64]:
        """Wrist joint rates (rad/s), ground truth."""
        return self.data.qvel[self._wr_v].copy()

    @property
    def arm_q(self) -> NDArray[np.float64]:
        """Arm joint angles (rad), ground truth."""
        return self.data.qpos[self._arm_q].copy()

    @property
    def q(self) -> NDArray[np.float64]:
        """The 8 robot joint angles [arm, pitch, roll] (the Pinocchio model's order)."""
        return np.concatenate([self.arm_q, self.wrist_q])

    def tip_pose(self) -> NDArray[np.float64]:
        """(4, 4) pose of the utensil tip in the arm base (= world) frame."""
        T = np.eye(4)
        T[:3, :3] = self.data.site_xmat[self._tip_site].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self._tip_site]
        return T

    def tilt_deg(self) -> float:
        """Ground-truth tilt of the utensil's up vector from vertical (degrees)."""
        from articutool.tool.kinematics import tilt_from_vertical

        return math.degrees(float(tilt_from_vertical(self.tip_pose()[:3, 1])))

    def tool_base_tilt_deg(self) -> float:
        """Tilt of the tool base F0's x axis (the up vector at zero wrist angles), degrees."""
        from articutool.tool.kinematics import tilt_from_vertical

        R = self.data.site_xmat[self._imu_site].reshape(3, 3)
        return math.degrees(float(tilt_from_vertical(R[:, 0])))

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per CPU second of this thread, over every step so far."""
        return self._sim_stepped / self._cpu if self._cpu > 0 else math.nan

    # ------------------------------------------------------------------ stepping --
    def step(self, tick: bool = True) -> None:
        """One physics step; the tool ticks every loop period (``tick=False``: tool off)."""
        self._advance(1, tick)

    def run(self, seconds: float, tick: bool = True) -> None:
        """Advance the world by ``seconds``."""
        if not (math.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"seconds must be a finite number >= 0; got {seconds}")
        self._steps(round(seconds / self.dt), tick)

    def run_until(self, done: Callable[[], bool], timeout: float) -> bool:
        """Step until ``done()`` (checked every loop period) or ``timeout`` s; True if done."""
        t_end = self.time + timeout
        while self.time < t_end - 1e-12:
            self._steps(self._steps_per_tick, True)
            if done():
                return True
        return False

    def _steps(self, n: int, tick: bool) -> None:
        """``n`` physics steps, in batches that end where the tool ticks."""
        while n > 0:
            k = min(n, self._steps_per_tick - self._step_count % self._steps_per_tick)
            self._advance(k, tick)
            n -= k

    def _advance(self, n: int, tick: bool) -> None:
        """``n`` physics steps of which only the last may end on a tool tick: per step the
        arm servos' references, the wrist motors' velocity loop, ``mj_step`` and the sensor
        samples due; then the tick. The same operations in the same order as one step at a
        time (bit-identical), with the per-step Python cut to what depends on the step: the
        arm's references for the batch are sampled at once, at the times the physics will
        reach (MuJoCo adds ``dt`` to ``time`` each step, so does ``np.add.accumulate``)."""
        m, d, dt = self.model, self.data, self.dt
        c0 = time.thread_time()
        t_start = float(d.time)
        refs, refv = self._arm_references(n)
        seen = np.empty((n, 6))
        ctrl, qpos, qvel, sens = d.ctrl, d.qpos, d.qvel, d.sensordata
        act_pos, act_vel, arm_q = self._act_pos, self._act_vel, self._arm_q
        (w0, w1), (v0, v1) = self._act_wr, self._wr_v
        kv, ki, tq = self._kv, self._ki, self._tq
        lim = tq / ki  # anti-windup: the integral never asks for more than the stall torque
        vi0, vi1 = float(self._vel_int[0]), float(self._vel_int[1])
        hold = self._hold_wrist
        model = self.motors.model
        # Velocity mode: the goal does not depend on the angles, so it holds for the batch.
        fixed = None if hold or model.mode != "velocity" else model.velocity_targets(self.wrist_q)
        on0, on1 = (True, True) if hold else (bool(model.torque[0]), bool(model.torque[1]))
        s_acc, s_gyro, s_f, s_t = self._s_acc, self._s_gyro, self._s_force, self._s_torque
        for k in range(n):
            ctrl[act_pos] = refs[k]
            ctrl[act_vel] = refv[k]
            seen[k] = qpos[arm_q]
            # The XC430 velocity loop (PI) → joint torque, limited to the stall torque.
            if hold:
                g0 = g1 = 0.0
            else:
                goal = fixed if fixed is not None else model.velocity_targets(self.wrist_q)
                g0, g1 = float(goal[0]), float(goal[1])
            e0, e1 = g0 - float(qvel[v0]), g1 - float(qvel[v1])
            vi0 = min(max(vi0 + e0 * dt, -lim), lim) if on0 else 0.0
            vi1 = min(max(vi1 + e1 * dt, -lim), lim) if on1 else 0.0
            ctrl[w0] = min(max(kv * e0 + ki * vi0, -tq), tq) if on0 else 0.0
            ctrl[w1] = min(max(kv * e1 + ki * vi1, -tq), tq) if on1 else 0.0
            mujoco.mj_step(m, d)
            if tick:
                t = d.time
                if t >= self._next_imu - 1e-9:
                    self.imu.push(sens[s_acc:s_acc + 3].copy(), sens[s_gyro:s_gyro + 3].copy(),
                                  t)
                    self._next_imu += self._imu_period
                if t >= self._next_ft - 1e-9:
                    self.ft.push(sens[s_f:s_f + 3].copy(), sens[s_t:s_t + 3].copy(), t)
                    self._next_ft += self._ft_period
        if sum(d.warning[w].number for w in _RESET_WARNINGS) != self._resets:
            self._raise_reset(t_start, n)
        self._vel_int = np.array([vi0, vi1])
        err = float(np.max(np.abs(seen - refs)))
        self.arm_tracking_error = max(self.arm_tracking_error, err)
        self._step_count += n
        ticked = tick and self._step_count % self._steps_per_tick == 0
        if ticked:
            self.tool.tick(self.time)
            self.motors.check_stops()
            self._classify()
        self._cpu += time.thread_time() - c0
        self._sim_stepped += n * dt
        if ticked:
            for fn in self.on_tick:
                fn(self)

    def _raise_reset(self, t_start: float, n: int) -> None:
        """Raise :class:`PhysicsResetError` naming the warning, the time and the body whose degree
        of freedom went bad (MuJoCo's ``warning.lastinfo``)."""
        m, d = self.model, self.data
        self._resets = sum(d.warning[w].number for w in _RESET_WARNINGS)
        what = []
        for w in _RESET_WARNINGS:
            if d.warning[w].number:
                dof = int(d.warning[w].lastinfo)
                body = (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.dof_bodyid[dof]))
                        if w != mujoco.mjtWarning.mjWARN_BADQPOS and 0 <= dof < m.nv else None)
                what.append(f"{w.name} ×{d.warning[w].number} at "
                            + (f"DOF {dof} (body {body!r})" if body else f"index {dof}"))
        raise PhysicsResetError(f"MuJoCo reset the simulation after an instability between "
                           f"t = {t_start:.3f} and {t_start + n * self.dt:.3f} s: "
                           + "; ".join(what))

    def _arm_references(self, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The arm servos' position and velocity references for the next ``n`` steps (n, 6):
        the trajectory being followed sampled at each step's time, held at its end (at rest)
        once it is over; else the held reference."""
        traj = self._arm_traj
        if traj is None:
            return (np.broadcast_to(self._arm_ref, (n, 6)),
                    np.broadcast_to(self._arm_ref_v, (n, 6)))
        times = np.full(n, self.dt)
        times[0] = self.data.time
        t = np.add.accumulate(times) - self._arm_t0
        refs, refv = traj.sample(t)
        over = t >= traj.duration
        refv[over] = 0.0
        if over.any():
            self._arm_traj = None
        self._arm_ref, self._arm_ref_v = refs[-1].copy(), refv[-1].copy()
        return refs, refv

    def follow_arm(self, traj: JointTrajectory, wait: bool = True, settle_s: float = 0.2) -> None:
        """Start the arm on ``traj`` (its six arm joints, any order; extra wrist joints are
        ignored — the tool gets its own commands). ``wait``: run it to the end + ``settle_s``."""
        names = self.layout.arm_joints
        missing = [n for n in names if n not in traj.joint_names]
        if missing:
            raise ValueError(f"trajectory joint_names lack the arm joints {missing}")
        idx = [traj.joint_names.index(n) for n in names]
        arm = JointTrajectory(tuple(names), traj.times, traj.positions[:, idx],
                              traj.velocities[:, idx])
        lo, hi = self.spec.arm.lower, self.spec.arm.upper
        bad = np.argwhere((arm.positions < lo - 1e-9) | (arm.positions > hi + 1e-9))
        if bad.size:
            k, j = (int(v) for v in bad[0])
            raise ValueError(f"trajectory point {k}: {names[j]} = {arm.positions[k, j]:.4g} rad "
                             f"is outside [{lo[j]:.4g}, {hi[j]:.4g}]")
        self._arm_traj = arm
        self._arm_t0 = self.time
        if wait:
            self.run(arm.duration + settle_s)

    def move_arm(self, q: ArrayLike, duration: float | None = None, wait: bool = True) -> None:
        """Rest-to-rest joint motion from the present reference to ``q`` within speed limits."""
        traj = smooth_joint_motion(self._arm_ref, q, self.spec.arm.max_velocity,
                                   self.layout.arm_joints, duration)
        self.follow_arm(traj, wait)

    def stop_arm(self) -> None:
        """Stop following: hold the arm where it is now, at rest."""
        self._arm_traj = None
        self._arm_ref = self.arm_q
        self._arm_ref_v = np.zeros(6)

    @property
    def arm_busy(self) -> bool:
        """True while an arm trajectory is being followed."""
        return self._arm_traj is not None

    # ---------------------------------------------------------------- food --
    @property
    def n_items(self) -> int:
        """Number of food items (pieces, particles, strands)."""
        return self.ledger.n_items

    @property
    def spills(self) -> list[acc.SpillEvent]:
        """Every spill event so far (:mod:`articutool.sim.accounting`)."""
        return self.ledger.spills

    def _classify(self) -> None:
        self.ledger.classify(self.time)

    def eat_from_utensil(self) -> float:
        """The user takes the bite: what is on the utensil now — pieces, particles and
        noodle strands alike — is eaten (moved out of the world, never counted again).
        Returns the grams eaten. (The simulated user does not bite or chew; the feeding tree
        presents the bite and this stands for the user taking it.)"""
        return self.ledger.eat_from_utensil()

    def tare_ft(self, settle_s: float = 0.0) -> None:
        """Tare the F/T sensor as a user would: after ``settle_s`` at rest, average its next
        ``spec.ft.tare_samples`` samples (the utensil should be empty and still)."""
        self.run(settle_s)
        self.ft.tare()
        self.run_until(lambda: not self.ft.tare_pending, 1.0)
        self.ft.history.clear()  # samples before the new offset are not comparable
        self._tare_R = self.data.site_xmat[self._ft_site].reshape(3, 3).copy()

    def ft_comparable(self, tol_deg: float = 3.0) -> bool:
        """True when gravity, seen from the sensor, is within ``tol_deg`` of where it was at
        the last tare: only then does the tared force weigh the load (the utensil's own
        weight was removed in that orientation; a turn about the vertical does not matter)."""
        R = self.data.site_xmat[self._ft_site].reshape(3, 3)
        c = float((self._tare_R.T @ _ZUP) @ (R.T @ _ZUP))
        return math.degrees(math.acos(min(1.0, max(-1.0, c)))) <= tol_deg

    def place_load(self, settle_s: float = 0.5) -> float:
        """Put the load (``load_g``) on the utensil the way a scoop leaves it
        (:mod:`articutool.sim.loading`), at the utensil's velocity, then run ``settle_s``;
        returns the mass on the utensil after that (g).

        Rigid pieces are deposited one at a time from the supply over the whole dish (a fork:
        its tines), each let go just above what is under its spot, 0.3 s apart, while each
        brings the mass on the utensil nearer the load (to within half a piece); what does
        not stay falls where physics takes it. Particles fill the dish from its floor up (a
        liquid poured in), so a load the spoon can hold stays.
        """
        if not self.layout.parked or self.ledger.active.any():
            raise RuntimeError("place_load needs a world built with load_g, not yet placed")
        u = self.spec.utensil(self.utensil)
        body = self.model.body("utensil").id
        fp = self.params.food(self.food or "")
        if isinstance(fp, Granular):
            self._deposit(u, body, float(self.load_g or 0.0))
        else:
            pts = pour_lattice(u, self.layout.piece_size)
            if len(pts) < self.n_items:
                raise ValueError(f"load_g: {self.n_items} particles do not fit on the "
                                 f"{self.utensil} (at most {len(pts)}, "
                                 f"{self.max_load_g():.1f} g); place less")
            for k in range(self.n_items):
                self.ledger.unpark(k, body, pts[k])
            mujoco.mj_forward(self.model, self.data)
        self.run(settle_s)
        return self.masses_g()["utensil"]

    def _deposit(self, u: Any, body: int, target_g: float) -> None:
        """Deposit supply pieces over the dish while each brings the load on the utensil
        nearer ``target_g`` (see :meth:`place_load`)."""
        m, d = self.model, self.data
        rng = np.random.default_rng(self.seed + 7)
        # Rays down the dish's normal start 5 cm above its rim: above any heap it holds.
        depth_m = u.physics.bowl[2] if u.physics.bowl is not None else 0.0
        top = u.tip_x + depth_m + 0.05
        gid = np.zeros(1, dtype=np.int32)
        node = self.ledger.geom_node
        for k in range(self.n_items):
            # The next piece goes on only if the load comes nearer the target with it.
            if self.masses_g()["utensil"] + self.ledger.item_g[k] / 2 > target_g:
                break
            bid = int(self.ledger.item_body[k])
            g0, gn = m.body_geomadr[bid], m.body_geomnum[bid]
            thick = float(max(m.geom_size[g0:g0 + gn, 0]))  # a flat piece's half thickness
            reach = float(max(np.linalg.norm(m.geom_pos[g], ord=2) + m.geom_rbound[g]
                              for g in range(g0, g0 + gn)))
            y, z = deposit_spot(u, reach, rng)
            R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
            start = p + R @ np.array([top, y, z])
            hit = mujoco.mj_ray(m, d, start, -R[:, 0], None, 1, -1, gid)
            # What is under the spot: a piece already there or the dish (else its surface).
            if hit >= 0 and node[gid[0]] >= -1:
                under = top - hit
            else:
                under = u.tip_x + min(dish_surface_height(u, y, z), depth_m)
            local = (under + thick + DEPOSIT_CLEARANCE_M, y, z)
            # Lying flat (the piece's own z along the dish's normal), turned at random about it.
            yaw = float(rng.uniform(0.0, 2.0 * math.pi))
            flat = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
            spin = np.array([[math.cos(yaw), -math.sin(yaw), 0.0],
                             [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
            self.ledger.unpark(k, body, local, R @ flat @ spin)
            self.run(0.3)

    def capacity_bound_g(self, food: str) -> float:
        """The most this world's utensil can hold of ``food`` (g): a physical bound
        (:func:`articutool.sim.loading.max_load_g`); loads above it are refused."""
        return utensil_capacity_bound_g(self.spec, self.params, food, self.utensil)

    def max_load_g(self) -> float:
        """The most a liquid load :meth:`place_load` can pour onto this utensil (g); infinite
        for pieces (they are dropped one by one, what does not stay falls)."""
        if isinstance(self.params.food(self.food or ""), Granular):
            return math.inf
        u = self.spec.utensil(self.utensil)
        return len(pour_lattice(u, self.layout.piece_size)) * self.layout.piece_mass * 1000.0

    def ft_mass_g(self, window_s: float = 1.0) -> float:
        """Mass on the utensil (g) as the F/T sensor measures it: the mean tared force over
        the last ``window_s`` projected on gravity in the sensor frame (meaningful at rest)."""
        n = max(1, round(window_s * self.spec.ft.rate_hz))
        hist = list(self.ft.history)[-n:]
        if not hist:
            return math.nan
        f = np.mean([s.force for s in hist], axis=0)
        R = self.data.site_xmat[self._ft_site].reshape(3, 3)
        down = R.T @ np.array([0.0, 0.0, -1.0])  # gravity direction in the sensor frame
        # The sensor reads the reaction on the utensil: extra weight pulls along −down.
        return float(-f @ down / self.spec.imu.gravity * 1000.0)

    @property
    def strands(self) -> bool:
        """The food is strands (noodles): an item may hang from the utensil onto a surface."""
        return self.food is not None and isinstance(self.params.food(self.food), Strands)

    def utensil_mass_g(self) -> float:
        """The mass on the utensil as an experimenter weighing it would find (g): the items on
        it (:meth:`masses_g`), or for strands what the utensil bears of them
        (:meth:`carried_g`)."""
        return self.carried_g() if self.strands else self.masses_g()["utensil"]

    def carried_g(self) -> float:
        """What a scale under the utensil reads (g): the downward force the food's
        contacts put on the utensil, over g — a strand hanging from the fork onto a surface
        counts as much as the fork bears of it. The F/T sensor measures the same force plus
        the utensil's own weight and inertia; this reads it without the sensor's noise, tare
        or orientation limits; the mean over the last 0.5 s (meaningful at rest)."""
        return self.ledger.carried_force_z() / -self.spec.imu.gravity * 1000.0

    def item_masses_g(self) -> NDArray[np.float64]:
        """Grams of each food item (pieces vary in size; particles and strands do not)."""
        return self.ledger.item_g.copy()

    def item_classes(self) -> NDArray[np.int64]:
        """Where each food item is now: its code in ``accounting.CLASS_NAMES`` (utensil,
        container, table, …), or −1 for a piece of a load not yet placed."""
        return self.ledger.item_classes()

    def masses_g(self) -> dict[str, float]:
        """Mass (g) per class: utensil, container, table, critical, airborne, eaten."""
        return self.ledger.masses_g()

    def report(self, measure_ft: bool = False) -> FoodReport:
        """The food report now (``measure_ft``: include the F/T-measured mass, when the
        sensor is oriented as at its tare — see :meth:`ft_comparable`)."""
        g = self.masses_g()
        return FoodReport(
            t=round(self.time, 4), food=self.food, utensil=self.utensil,
            on_utensil_g=g["utensil"], in_bowl_g=g["container"], table_g=g["table"],
            critical_g=g["critical"], airborne_g=g["airborne"], eaten_g=g["eaten"],
            total_g=float(self.ledger.item_g[self.ledger.active].sum()),
            spills=list(self.spills),
            ft_mass_g=self.ft_mass_g() if measure_ft and self.ft_comparable() else None,
            realtime_factor=self.realtime_factor,
            arm_tracking_error_rad=self.arm_tracking_error,
        )
