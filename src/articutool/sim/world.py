"""The feeding world: MuJoCo physics with the Articutool's own onboard software in the loop.

:class:`FeedingWorld` builds the MJCF from the spec, the scene and a food
(:mod:`articutool.sim.mjcf`), lets the food settle, then runs the unchanged
:class:`~articutool.tool.runtime.ToolRuntime` on MuJoCo-backed drivers
(:mod:`articutool.sim.mj_drivers`) at ``spec.wrist.loop_rate_hz`` in lockstep with the physics:
each physics step applies the arm servos' references and the wrist motors' torques, steps,
then emits IMU and F/T samples at their rates; every loop period the runtime ticks on the
simulation clock. Commands reach the tool through ``world.tool``, the same ``ToolAPI`` the
link serves.

The arm follows a :class:`~articutool.trajectory.JointTrajectory` with joint servos (PD with
velocity feed-forward, torque-limited by the spec's efforts), so contacts see the real
velocity of the utensil — never a teleported body. The tracking error is recorded.

Food accounting (:mod:`articutool.sim.accounting`) runs every loop period: the mass on the
utensil, in its container, on the table, on critical places, in the air, eaten; every spill
with its time, mass and place. Food entering the scene's ``mouth`` region is eaten (removed).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.arm.scene import Box, Cylinder, Scene, Sphere
from articutool.sim import accounting as acc
from articutool.sim.mj_drivers import MjFTDriver, MjImuDriver, MjMotorDriver
from articutool.sim.mjcf import (
    FT_SITE,
    IMU_SITE,
    WorldLayout,
    build_mjcf,
    spoon_dish,
    tip_site_name,
)
from articutool.sim.params import Granular, PhysicsParams
from articutool.sim.pieces import piece_extent
from articutool.spec import Spec, load_spec
from articutool.tool.drivers.motor_model import MotorPlant
from articutool.tool.runtime import ToolRuntime
from articutool.trajectory import JointTrajectory

__all__ = ["FeedingWorld", "FoodReport", "smooth_joint_motion"]

_UTENSIL_NODE, _OTHER_NODE, _SURFACE0 = -1, -2, -10
_ZUP = np.array([0.0, 0.0, 1.0])


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
        if load_g is not None and not (math.isfinite(load_g) and load_g > 0):
            raise ValueError(f"load_g must be a finite mass > 0 g; got {load_g}")
        if load_g is not None and food is None:
            raise ValueError("load_g needs a food")
        self.layout: WorldLayout = build_mjcf(self.spec, self.scene, self.params, self.utensil,
                                              food, self.seed, load_g)
        self.model = mujoco.MjModel.from_xml_string(self.layout.xml)
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
        self._build_accounting()

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
        self.run(self.params.world.settle_s if settle and food is not None else 0.2, tick=False)
        self._hold_wrist = False
        self._next_imu = self.time
        self._next_ft = self.time
        self.tool.open()
        self.run(0.2)
        self.tare_ft()
        self._classify()

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
        m, d = self.model, self.data
        c0 = time.thread_time()
        self._arm_control()
        self._wrist_control()
        mujoco.mj_step(m, d)
        self._step_count += 1
        ticked = tick and self._step_count % self._steps_per_tick == 0
        if tick:
            self._emit_samples()
            if ticked:
                self.tool.tick(self.time)
                self.motors.check_stops()
                self._classify()
        self._cpu += time.thread_time() - c0
        self._sim_stepped += self.dt
        if ticked:
            for fn in self.on_tick:
                fn(self)

    def run(self, seconds: float, tick: bool = True) -> None:
        """Advance the world by ``seconds``."""
        if not (math.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"seconds must be a finite number >= 0; got {seconds}")
        for _ in range(round(seconds / self.dt)):
            self.step(tick)

    def run_until(self, done: Callable[[], bool], timeout: float) -> bool:
        """Step until ``done()`` (checked every loop period) or ``timeout`` s; True if done."""
        t_end = self.time + timeout
        while self.time < t_end - 1e-12:
            for _ in range(self._steps_per_tick):
                self.step()
            if done():
                return True
        return False

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

    def _arm_control(self) -> None:
        d = self.data
        if self._arm_traj is not None:
            t = self.time - self._arm_t0
            q, v = self._arm_traj.sample(t)
            self._arm_ref, self._arm_ref_v = q, v
            if t >= self._arm_traj.duration:
                self._arm_traj = None
                self._arm_ref_v = np.zeros(6)
        d.ctrl[self._act_pos] = self._arm_ref
        d.ctrl[self._act_vel] = self._arm_ref_v
        err = float(np.max(np.abs(d.qpos[self._arm_q] - self._arm_ref)))
        self.arm_tracking_error = max(self.arm_tracking_error, err)

    def _wrist_control(self) -> None:
        """The XC430 velocity loop (PI) → joint torque, limited to the stall torque."""
        d = self.data
        if self._hold_wrist:
            goal, on = np.zeros(2), np.ones(2, dtype=bool)
        else:
            goal, on = self.motors.model.velocity_targets(self.wrist_q), self.motors.model.torque
        e = goal - d.qvel[self._wr_v]
        self._vel_int = np.where(on, self._vel_int + e * self.dt, 0.0)
        # Anti-windup: the integral never asks for more than the stall torque.
        lim = self._tq / self._ki
        self._vel_int = np.clip(self._vel_int, -lim, lim)
        tau = np.clip(self._kv * e + self._ki * self._vel_int, -self._tq, self._tq)
        d.ctrl[self._act_wr] = np.where(on, tau, 0.0)

    def _emit_samples(self) -> None:
        d, t = self.data, self.time
        if t >= self._next_imu - 1e-9:
            self.imu.push(d.sensordata[self._s_acc:self._s_acc + 3].copy(),
                          d.sensordata[self._s_gyro:self._s_gyro + 3].copy(), t)
            self._next_imu += self._imu_period
        if t >= self._next_ft - 1e-9:
            self.ft.push(d.sensordata[self._s_force:self._s_force + 3].copy(),
                         d.sensordata[self._s_torque:self._s_torque + 3].copy(), t)
            self._next_ft += self._ft_period

    # ---------------------------------------------------------------- accounting --
    def _build_accounting(self) -> None:
        m, lay = self.model, self.layout
        self._surface_names: list[str] = []
        codes = []
        node = np.full(m.ngeom, _OTHER_NODE, dtype=np.int64)
        for gname, place in lay.places.items():
            node[m.geom(gname).id] = _SURFACE0 - len(self._surface_names)
            self._surface_names.append(gname.split("/")[1])
            codes.append(acc.PLACE_CODES[place])
        self._surface_codes = np.array(codes, dtype=np.int64)
        for gname in lay.utensil_geoms:
            node[m.geom(gname).id] = _UTENSIL_NODE
        item_body = []
        for k, b in enumerate(lay.food_bodies):
            bid = m.body(b).id
            node[m.body_geomadr[bid]:m.body_geomadr[bid] + m.body_geomnum[bid]] = k
            item_body.append(bid)
        n_bodies = len(lay.food_bodies)
        self._strand_verts: list[NDArray[np.int64]] = []  # each strand's capsule bodies
        for k, sname in enumerate(lay.food_strands):  # a strand: one item, all its capsules
            for i in range(lay.strand_segments):
                node[m.geom(f"{sname}/{i}").id] = n_bodies + k
            self._strand_verts.append(np.array(
                [m.body(f"{sname}/{i}").id for i in range(lay.strand_segments)], dtype=np.int64))
            item_body.append(m.body(f"{sname}/0").id)  # its root (free joint)
        self._geom_node = node
        self._item_body = np.array(item_body, dtype=np.int64)
        self.n_items = len(item_body)
        # Grams per item: a body's own mass (pieces vary in size), a strand's from the model.
        self._item_g = np.array([m.body_mass[b] * 1000.0 for b in item_body[:n_bodies]]
                                + [lay.piece_mass * 1000.0] * len(lay.food_strands))
        self._active = np.full(self.n_items, not lay.parked, dtype=bool)
        if lay.parked:  # parked pieces never sleep, so placing them needs no wake-up
            for b in item_body:
                m.tree_sleep_policy[m.body_treeid[b]] = int(mujoco.mjtSleepPolicy.mjSLEEP_NEVER)
        self._codes = np.full(self.n_items, acc.AIRBORNE, dtype=np.int64)
        self._where = np.full(self.n_items, -1, dtype=np.int64)
        self._spill = acc.SpillTracker(self.n_items, self.params.world.spill_dwell_s)
        self.spills: list[acc.SpillEvent] = []
        self._mouth = next(((np.asarray(r.xyz), r.radius) for r in self.scene.regions
                            if r.name == "mouth"), None)

    def _contacts(self) -> tuple[NDArray, NDArray, NDArray]:
        d = self.data
        nc = d.ncon
        if nc == 0 or self.n_items == 0:
            e = np.zeros((0, 2), dtype=np.int64)
            return e, np.zeros(0, dtype=np.int64), e
        nodes = self._geom_node[d.contact.geom[:nc]]
        a, b = nodes[:, 0], nodes[:, 1]
        ii = (a >= 0) & (b >= 0) & (a != b)
        item_item = np.column_stack([a[ii], b[ii]])
        iu = np.concatenate([a[(a >= 0) & (b == _UTENSIL_NODE)],
                             b[(b >= 0) & (a == _UTENSIL_NODE)]])
        sa, sb = (a >= 0) & (b <= _SURFACE0), (b >= 0) & (a <= _SURFACE0)
        item_surface = np.concatenate([np.column_stack([a[sa], _SURFACE0 - b[sa]]),
                                       np.column_stack([b[sb], _SURFACE0 - a[sb]])])
        return item_item, iu, item_surface

    def _classify(self) -> None:
        if self.n_items == 0:
            return
        self._eat()
        ii, iu, isf = self._contacts()
        asleep = self.data.body_awake[self._item_body] == 0
        # A sleeping item has no contacts to classify it by, but it is at rest on something
        # static: the robot never sleeps and wakes what it touches. One that was last seen on
        # the utensil or in the air gets the place below it.
        prev, prev_where = self._codes.copy(), self._where.copy()
        for k in np.flatnonzero(asleep & ((prev == acc.UTENSIL) | (prev == acc.AIRBORNE))):
            prev[k], prev_where[k] = self._place_below(self.data.xpos[self._item_body[k]])
        codes, where = acc.classify_items(self.n_items, ii, iu, isf, self._surface_codes,
                                          prev, prev_where, asleep)
        # An event each time an item has stayed on a spill place worse than any it reached
        # before for the dwell time (a drop that lands on the table and rolls onto the floor
        # is two events; the spilled mass counts it once, at the floor: acc.spilled_by_place).
        for k, code, w, t0 in self._spill.update(self.time, self.spec.wrist.period, codes,
                                                  where, self._active):
            self.spills.append(acc.SpillEvent(
                t=round(t0, 4), mass_g=float(self._item_g[k]), place=acc.CLASS_NAMES[code],
                where=self._surface_names[w] if w >= 0 else "", item=k))
        self._codes, self._where = codes, where

    def _place_below(self, p: NDArray[np.float64]) -> tuple[int, int]:
        """(class, surface index) of the least severe place whose object holds point ``p``
        (its footprint, up to 5 cm above it); the floor (critical) if none."""
        best = (acc.CRITICAL, -1)
        for i, name in enumerate(self._surface_names):
            o = self.scene.get(name)
            local = o.rotation.T @ (p - np.asarray(o.xyz))
            if isinstance(o, Cylinder):
                inside = (math.hypot(local[0], local[1]) <= o.radius
                          and -o.length / 2 <= local[2] <= o.length / 2 + 0.05)
            elif isinstance(o, Box):
                h = np.asarray(o.size) / 2
                inside = bool(np.all(np.abs(local[:2]) <= h[:2])
                              and -h[2] <= local[2] <= h[2] + 0.05)
            elif isinstance(o, Sphere):
                inside = float(np.linalg.norm(local)) <= o.radius + 0.05
            else:
                inside = local[2] <= 0.05
            code = int(self._surface_codes[i])
            if inside and code < best[0]:
                best = (code, i)
        return best

    def _eat(self) -> None:
        """Food that enters the mouth region is eaten: moved out of the world, frozen. A
        strand is eaten when any of its vertices enters it."""
        if self._mouth is None or self.n_items == 0:
            return
        c, r = self._mouth
        d = self.data
        n = len(self.layout.food_bodies)
        inside = np.zeros(self.n_items, dtype=bool)
        inside[:n] = np.linalg.norm(d.xpos[self._item_body[:n]] - c, axis=1) < r
        for k, verts in enumerate(self._strand_verts):
            inside[n + k] = bool(np.any(np.linalg.norm(d.xpos[verts] - c, axis=1) < r))
        self._remove_eaten(np.flatnonzero(inside & self._active & (self._codes != acc.EATEN)))

    def eat_from_utensil(self) -> float:
        """The user takes the bite: what is on the utensil now — pieces, particles and
        noodle strands alike — is eaten (moved out of the world, never counted again).
        Returns the grams eaten. (The simulated user does not bite or chew; the feeding tree
        presents the bite and this stands for the user taking it.)"""
        on = np.flatnonzero(self._active & (self._codes == acc.UTENSIL))
        self._remove_eaten(on)
        return float(self._item_g[on].sum())

    def _remove_eaten(self, items: NDArray[np.int64]) -> None:
        m, d = self.model, self.data
        n_bodies = len(self.layout.food_bodies)
        for k in items:
            if k >= n_bodies:  # a strand: its root's free joint carries the whole chain out
                name = self.layout.food_strands[k - n_bodies]
                for i in range(self.layout.strand_segments):
                    g = m.geom(f"{name}/{i}").id
                    m.geom_contype[g] = m.geom_conaffinity[g] = 0
                    b = m.geom_bodyid[g]
                    m.body_contype[b] = m.body_conaffinity[b] = 0
                    m.body_gravcomp[b] = 1.0
                j = m.body_jntadr[self._item_body[k]]
                qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
                d.qpos[qa:qa + 3] = (100.0 + k, 0.0, 10.0)
                d.qvel[va:va + 6] = 0.0
                self._codes[k] = acc.EATEN
                continue
            b = self._item_body[k]
            g = slice(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b])
            m.geom_contype[g] = m.geom_conaffinity[g] = 0
            m.body_contype[b] = m.body_conaffinity[b] = 0
            m.body_gravcomp[b] = 1.0
            j = m.body_jntadr[b]
            qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
            d.qpos[qa:qa + 3] = (100.0 + k, 0.0, 10.0)
            d.qvel[va:va + 6] = 0.0
            self._codes[k] = acc.EATEN

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
        """Put the parked load (``load_g``) on the utensil, at the utensil's velocity, then
        run ``settle_s``; returns the mass on the utensil after that (g).

        Rigid pieces are dropped one by one from just above the dish (or the tines), 0.2 s
        apart, as a hand places them; what does not stay falls where physics takes it.
        Particles are laid on a lattice filling the dish from its floor up (a liquid poured
        in), so a load the spoon can hold stays.
        """
        if not self.layout.parked or self._active.any():
            raise RuntimeError("place_load needs a world built with load_g, not yet placed")
        u = self.spec.utensil(self.utensil)
        ph = u.physics
        body = self.model.body("utensil").id
        fp = self.params.food(self.food or "")
        if ph.kind == "spoon":
            zc, *_, depth = spoon_dish(u)
        else:
            assert ph.tine_length is not None
            zc, depth = u.tip_z - ph.tine_length / 2, 0.0
        if isinstance(fp, Granular):
            rng = np.random.default_rng(self.seed + 7)
            lift = depth + 0.6 * piece_extent(fp)
            for k in range(self.n_items):
                dy, dz = rng.uniform(-0.004, 0.004, 2)
                self._unpark(k, body, (u.tip_x + lift, dy, zc + dz))
                self.run(0.2)
        else:
            pts = self._pour_lattice()
            if len(pts) < self.n_items:
                raise ValueError(f"load_g: {self.n_items} particles do not fit on the "
                                 f"{self.utensil} (at most {len(pts)}, "
                                 f"{self.max_load_g():.1f} g); place less")
            for k in range(self.n_items):
                self._unpark(k, body, pts[k])
            mujoco.mj_forward(self.model, self.data)
        self.run(settle_s)
        return self.masses_g()["utensil"]

    def _pour_lattice(self) -> list[tuple[float, float, float]]:
        """Particle centres (utensil frame) filling the dish from its floor up, then heaped
        above its rim until the heap closes: every place a poured liquid can be put."""
        u = self.spec.utensil(self.utensil)
        if u.physics.kind != "spoon":
            return []
        zc, a, b, a0, b0, depth = spoon_dish(u)
        cell = self.layout.piece_size
        pts: list[tuple[float, float, float]] = []
        for layer in range(41):
            h = cell / 2 + layer * cell  # centre height above the floor
            # The dish widens with height (45° walls); above the rim the heap narrows.
            grow = min(h / depth, 1.0) - max(h - depth, 0.0) / depth if depth else 0.0
            al, bl = a0 + (a - a0) * grow - cell / 2, b0 + (b - b0) * grow - cell / 2
            if al < 0 and bl < 0 and layer > 0:
                break
            ni, nj = int(max(al, 0.0) / cell), int(max(bl, 0.0) / cell)
            pts += [(u.tip_x + h, j * cell, zc + i * cell)
                    for i in range(-ni, ni + 1) for j in range(-nj, nj + 1)]
        return pts

    def max_load_g(self) -> float:
        """The most a liquid load :meth:`place_load` can pour onto this utensil (g); infinite
        for pieces (they are dropped one by one, what does not stay falls)."""
        if isinstance(self.params.food(self.food or ""), Granular):
            return math.inf
        return len(self._pour_lattice()) * self.layout.piece_mass * 1000.0

    def _unpark(self, k: int, body: int, local: tuple[float, float, float]) -> None:
        """Give parked piece ``k`` its collisions and weight, at ``local`` in ``body``'s frame
        with ``body``'s velocity and orientation."""
        m, d = self.model, self.data
        R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
        v = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, v, 0)
        bid = int(self._item_body[k])
        g = slice(m.body_geomadr[bid], m.body_geomadr[bid] + m.body_geomnum[bid])
        # The broad phase filters on the body's OR of its geoms' bits, kept in the model.
        m.geom_contype[g] = m.body_contype[bid] = self.layout.food_contype
        m.geom_conaffinity[g] = m.body_conaffinity[bid] = self.layout.food_conaffinity
        m.body_gravcomp[bid] = 0.0
        m.tree_sleep_policy[m.body_treeid[bid]] = int(mujoco.mjtSleepPolicy.mjSLEEP_AUTO_ALLOWED)
        j = m.body_jntadr[bid]
        qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
        d.qpos[qa:qa + 3] = p + R @ np.asarray(local)
        d.qpos[qa + 3:qa + 7] = d.xquat[body]  # lying along the utensil
        d.qvel[va:va + 3] = v[3:]
        d.qvel[va + 3:va + 6] = 0.0
        self._active[k] = True
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

    def item_masses_g(self) -> NDArray[np.float64]:
        """Grams of each food item (pieces vary in size; particles and strands do not)."""
        return self._item_g.copy()

    def item_classes(self) -> NDArray[np.int64]:
        """Where each food item is now: its code in ``accounting.CLASS_NAMES`` (utensil,
        container, table, …), or −1 for a piece of a load not yet placed."""
        return np.where(self._active, self._codes, -1)

    def masses_g(self) -> dict[str, float]:
        """Mass (g) per class: utensil, container, table, critical, airborne, eaten."""
        g = np.bincount(self._codes[self._active], weights=self._item_g[self._active],
                        minlength=len(acc.CLASS_NAMES))
        return {name: float(g[i]) for i, name in enumerate(acc.CLASS_NAMES)}

    def report(self, measure_ft: bool = False) -> FoodReport:
        """The food report now (``measure_ft``: include the F/T-measured mass, when the
        sensor is oriented as at its tare — see :meth:`ft_comparable`)."""
        g = self.masses_g()
        return FoodReport(
            t=round(self.time, 4), food=self.food, utensil=self.utensil,
            on_utensil_g=g["utensil"], in_bowl_g=g["container"], table_g=g["table"],
            critical_g=g["critical"], airborne_g=g["airborne"], eaten_g=g["eaten"],
            total_g=float(self._item_g[self._active].sum()),
            spills=list(self.spills),
            ft_mass_g=self.ft_mass_g() if measure_ft and self.ft_comparable() else None,
            realtime_factor=self.realtime_factor,
            arm_tracking_error_rad=self.arm_tracking_error,
        )
