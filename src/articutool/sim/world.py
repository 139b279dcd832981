"""The feeding world: MuJoCo physics with the Articutool's own onboard software in the loop.

:meth:`FeedingWorld.build` builds a world's parts from a
:class:`~articutool.sim.build.WorldConfig` (the spec, the scene, a food, the seed…;
:mod:`articutool.sim.build`: the MJCF, the model, the drivers, the tool), lets the food
settle, then starts the unchanged :class:`~articutool.tool.runtime.ToolRuntime` on
MuJoCo-backed drivers (:mod:`articutool.sim.mj_drivers`) at ``spec.wrist.loop_rate_hz`` in
lockstep with the physics and tares the F/T sensor: each physics step applies the arm servos'
references and the wrist motors' torques, steps, then emits IMU and F/T samples at their
rates; every loop period the runtime ticks on the simulation clock (:attr:`FeedingWorld.time`).
Commands reach the tool through ``world.tool``, the same ``ToolAPI`` the link serves. For
speed the steps between two ticks run as one batch with the per-step Python cut to what
depends on the step, and a settled pile is restored rather than settled again; both are
bit-identical to stepping one at a time and settling afresh (``tests/test_sim_speed.py``;
where the time goes: docs/simulation.md, *Speed*).

One stepping loop — arm servos, the wrist's velocity loop, sensors, the tool's tick — and the
arm-motion API around it; the food ledger (``world.ledger``), the weighing
(``world.weighing``) and the load placement (``world.placement``) are objects the world owns,
used directly.

The arm follows a :class:`~articutool.trajectory.JointTrajectory` with joint servos (PD with
velocity feed-forward, torque-limited by the spec's efforts), so contacts see the real
velocity of the utensil — never a teleported body. The tracking error is recorded.

The food ledger (:class:`~articutool.sim.ledger.FoodLedger`, rules in
:mod:`articutool.sim.accounting`) runs every loop period: the mass on the utensil, in its
container, on the table, on critical places, in the air, eaten; every spill with its time,
mass and place. Food entering the scene's ``mouth`` region is eaten (removed). Weighing the
utensil (the F/T sensor's tare and readings, a scale): :mod:`articutool.sim.weighing`.
Placing a load by hand: :mod:`articutool.sim.placement`.
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

from articutool.arm.scene import Cylinder
from articutool.sim import accounting as acc
from articutool.sim.bowl_liquid import BowlLiquid
from articutool.sim.build import (
    SettleCache,
    SettledState,
    WorldConfig,
    WorldParts,
    build_parts,
)
from articutool.sim.params import Granular, Liquid, Strands
from articutool.sim.placement import LoadPlacement
from articutool.sim.weighing import Weighing
from articutool.trajectory import JointTrajectory, smooth_joint_motion

__all__ = ["REPORT_JSON_KEYS", "FeedingWorld", "PhysicsResetError", "SettleCache", "WorldReport"]

# MuJoCo's warnings on which mj_step resets mjData to the model's defaults (its "simulation is
# unstable" reset: NaN, Inf or huge qpos/qvel/qacc). Everything after is not the run's physics.
_RESET_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                   mujoco.mjtWarning.mjWARN_BADQACC)

# The keys of a world report's masses in its JSON form (``articutool sim --json``), by the
# ledger's class names (:meth:`~articutool.sim.ledger.FoodLedger.masses_g`).
REPORT_JSON_KEYS = {"utensil": "on_utensil_g", "container": "in_bowl_g", "table": "table_g",
                    "critical": "critical_g", "airborne": "airborne_g", "eaten": "eaten_g"}


class PhysicsResetError(RuntimeError):
    """MuJoCo reset the simulation after a numerical instability: the arm, the wrist and the
    food jumped back to the model's defaults, so the run's outcome is meaningless: it stops
    here and is never counted."""


def _model_bytes(m: mujoco.MjModel) -> bytes:
    """The compiled model as MuJoCo saves it (every number and name): its identity."""
    buf = np.empty(mujoco.mj_sizeModel(m), dtype=np.uint8)
    mujoco.mj_saveModel(m, None, buf)
    return buf.tobytes()


@dataclass
class WorldReport:
    """What the world reports at time ``t``: where the food is, every spill so far, the F/T
    mass, the real-time factor and the arm's tracking error. ``masses_g``: grams per
    class, keyed as the ledger's (:meth:`FoodLedger.masses_g
    <articutool.sim.ledger.FoodLedger.masses_g>`: utensil, container, table,
    critical, airborne, eaten)."""

    t: float
    food: str | None
    utensil: str
    masses_g: dict[str, float]
    total_g: float
    spills: list[acc.SpillEvent] = field(default_factory=list)
    ft_mass_g: float | None = None  # as the F/T sensor measures it (at rest, level)
    realtime_factor: float = math.nan
    arm_tracking_error_rad: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: the masses flat under :data:`REPORT_JSON_KEYS`, spills as a list
        of dicts."""
        d = asdict(self)
        masses = d.pop("masses_g")
        out = {k: d.pop(k) for k in ("t", "food", "utensil")}
        out.update({REPORT_JSON_KEYS[c]: masses[c] for c in REPORT_JSON_KEYS})
        out.update(d)
        out["spills"] = [asdict(s) for s in self.spills]
        return out


class FeedingWorld:
    """One simulated meal scene (see module doc); :meth:`build` makes one ready to run.

    The constructor wires parts already built (:func:`articutool.sim.build.build_parts`)
    and steps nothing: its world has the food where the MJCF put it, the wrist servos
    holding still and the tool not started.
    """

    def __init__(self, parts: WorldParts) -> None:
        self.config = c = parts.config
        self.spec, self.scene, self.params = c.spec, c.scene, c.params
        self.food, self.utensil, self.seed, self.load_g = c.food, str(c.utensil), c.seed, c.load_g
        self.layout, self.model, self.data = parts.layout, parts.model, parts.data
        self.index = parts.index
        self.wrist_range = parts.index.wrist_range
        self.ledger = parts.ledger
        self.motors, self.imu, self.ft, self.tool = parts.motors, parts.imu, parts.ft, parts.tool
        wm = self.params.wrist_motor
        self._kv, self._ki = wm.kv, wm.ki
        self._tq = self.spec.motors.stall_torque_nm
        self._vel_int = np.zeros(2)
        self._hold_wrist = True  # the wrist servos hold still until the tool starts
        self.dt = float(self.model.opt.timestep)
        self._steps_per_tick = round(self.spec.wrist.period / self.dt)
        self._imu_period = 1.0 / self.spec.imu.rate_hz
        self._ft_period = 1.0 / self.spec.ft.rate_hz
        self._next_imu = self._next_ft = math.inf  # no samples before the tool starts
        self._step_count = 0
        self._resets = 0  # MuJoCo's reset warnings seen so far (see PhysicsResetError)
        # Called after every tool tick with the world (recorders, loggers); not timed.
        self.on_tick: list[Callable[[FeedingWorld], None]] = []
        self._cpu = 0.0
        self._sim_stepped = 0.0
        self._arm_ref = self.arm_q
        self._arm_ref_v = np.zeros(6)
        self._arm_traj: JointTrajectory | None = None
        self._arm_t0 = 0.0
        self.arm_tracking_error = 0.0
        self.weighing = Weighing(self.spec, self.data, self.ft, self.index.ft_site, self.ledger,
                                 self.strands, self.run, self.run_until)
        fp = self.params.food(self.food) if self.food is not None else None
        self.placement = LoadPlacement(
            self.model, self.data, self.layout, self.ledger, self.spec, self.utensil,
            fp, self.load_g, self.seed, self.run)
        # A filled container of a granular food: its no-slip passes follow the utensil's tip
        # (``Granular.noslip_iterations_digging``, :meth:`_set_digging`).
        self._passes = int(self.model.opt.noslip_iterations)
        self._digging: tuple[int, NDArray[np.float64], float, float] | None = None
        if (isinstance(fp, Granular) and fp.noslip_iterations_digging is not None
                and self.layout.container and not self.layout.parked):
            box = self.scene.get(self.layout.container)
            assert isinstance(box, Cylinder)
            self._digging = (fp.noslip_iterations_digging, np.asarray(box.xyz[:2], float),
                             float(box.radius), float(box.xyz[2] + box.length / 2))
        # The container's SPH liquid (:mod:`articutool.sim.bowl_liquid`), stepped each tick.
        self.bowl: BowlLiquid | None = None
        if self.layout.container_liquid:
            box = self.scene.get(self.layout.container)
            assert isinstance(fp, Liquid) and isinstance(box, Cylinder)
            self.bowl = BowlLiquid(self.model, self.data, self.ledger, box,
                                   self.spec.utensil(self.utensil), fp, self.placement)

    @classmethod
    def build(cls, config: WorldConfig, *, settle: bool = True,
              settle_cache: SettleCache | None = None) -> FeedingWorld:
        """The world ``config`` describes, ready to run: its parts built
        (:func:`~articutool.sim.build.build_parts`), the food settled with the wrist held, the
        tool started and run 0.2 s, the F/T tared.

        ``settle``: let the food settle for ``params.world.settle_s`` before the tool starts
        (else 0.2 s, the servos only). ``settle_cache``: restores the settled state of an
        earlier world with the same model and start state instead of settling again
        (bit-identical; :class:`~articutool.sim.build.SettleCache`); ``None`` settles afresh.
        """
        world = cls(build_parts(config))
        food = config.food
        world._settle(world.params.world.settle_s if settle and food is not None else 0.2,
                      settle_cache)
        world._start_tool()
        world.run(0.2)
        world.weighing.tare()
        world.ledger.classify(world.time)
        return world

    @classmethod
    def make(cls, food: str | None = "pecans", utensil: str | None = None, *,
             settle: bool = True, settle_cache: SettleCache | None = None,
             **fields: Any) -> FeedingWorld:
        """``build(WorldConfig(food, utensil, **fields), settle=…, settle_cache=…)``: the
        fields are :class:`~articutool.sim.build.WorldConfig`'s."""
        return cls.build(WorldConfig(food, utensil, **fields), settle=settle,
                         settle_cache=settle_cache)

    def _settle(self, seconds: float, cache: SettleCache | None) -> None:
        """Run ``seconds`` with the tool off, or, with a :class:`SettleCache`, restore the
        state that run left last time (bit-identical to settling again)."""
        m, d = self.model, self.data
        if cache is None:
            self.run(seconds, tick=False)
            return
        h = hashlib.sha256(_model_bytes(m))
        for a in (d.qpos, d.qvel, m.tree_sleep_policy,
                  np.array([seconds, self._kv, self._ki, self._tq])):
            h.update(np.ascontiguousarray(a).tobytes())
        key = h.hexdigest()
        hit: SettledState | None = cache.take(key)
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

    def _start_tool(self) -> None:
        """Release the wrist to the tool's motors, start the sensors' samples and open the
        tool."""
        self._hold_wrist = False
        self._next_imu = self.time
        self._next_ft = self.time
        self.tool.open()

    # ----------------------------------------------------------------- accessors --
    @property
    def time(self) -> float:
        """Simulation time (s): the tool runtime's clock."""
        return float(self.data.time)

    @property
    def wrist_q(self) -> NDArray[np.float64]:
        """Wrist joint angles [pitch, roll] (rad), ground truth."""
        return self.data.qpos[self.index.wrist_q].copy()

    @property
    def wrist_qd(self) -> NDArray[np.float64]:
        """Wrist joint rates (rad/s), ground truth."""
        return self.data.qvel[self.index.wrist_v].copy()

    @property
    def arm_q(self) -> NDArray[np.float64]:
        """Arm joint angles (rad), ground truth."""
        return self.data.qpos[self.index.arm_q].copy()

    @property
    def q(self) -> NDArray[np.float64]:
        """The 8 robot joint angles [arm, pitch, roll] (the Pinocchio model's order)."""
        return np.concatenate([self.arm_q, self.wrist_q])

    def tip_pose(self) -> NDArray[np.float64]:
        """(4, 4) pose of the utensil tip in the arm base (= world) frame."""
        T = np.eye(4)
        T[:3, :3] = self.data.site_xmat[self.index.tip_site].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self.index.tip_site]
        return T

    def tilt_deg(self) -> float:
        """Ground-truth tilt of the utensil's up vector from vertical (degrees)."""
        from articutool.tool.kinematics import tilt_from_vertical

        return math.degrees(float(tilt_from_vertical(self.tip_pose()[:3, 1])))

    def tool_base_tilt_deg(self) -> float:
        """Tilt of the tool base F0's x axis (the up vector at zero wrist angles), degrees."""
        from articutool.tool.kinematics import tilt_from_vertical

        R = self.data.site_xmat[self.index.imu_site].reshape(3, 3)
        return math.degrees(float(tilt_from_vertical(R[:, 0])))

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per CPU second of this thread, over every step so far."""
        return self._sim_stepped / self._cpu if self._cpu > 0 else math.nan

    @property
    def stepping_cpu_s(self) -> float:
        """CPU seconds of the stepping thread spent in this world's steps so far (the clock
        of :attr:`realtime_factor`)."""
        return self._cpu

    @property
    def stepped_s(self) -> float:
        """Simulated seconds this world has stepped so far."""
        return self._sim_stepped

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
        ix = self.index
        act_pos, act_vel, arm_q = ix.act_pos, ix.act_vel, ix.arm_q
        (w0, w1), (v0, v1) = ix.act_wrist, ix.wrist_v
        kv, ki, tq = self._kv, self._ki, self._tq
        lim = tq / ki  # anti-windup: the integral never asks for more than the stall torque
        vi0, vi1 = float(self._vel_int[0]), float(self._vel_int[1])
        hold = self._hold_wrist
        model = self.motors.model
        # Velocity mode: the goal does not depend on the angles, so it holds for the batch.
        fixed = None if hold or model.mode != "velocity" else model.velocity_targets(self.wrist_q)
        on0, on1 = (True, True) if hold else (bool(model.torque[0]), bool(model.torque[1]))
        s_acc, s_gyro, s_f, s_t = ix.s_acc, ix.s_gyro, ix.s_force, ix.s_torque
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
            if self.bowl is not None:  # the container's liquid, stepped to this time
                self.bowl.advance()
            if self.placement.liquid is not None:  # the liquid load, stepped to this time
                self.placement.liquid.advance()
            self.ledger.classify(self.time)
            if self._digging is not None:
                self._set_digging(*self._digging)
        self._cpu += time.thread_time() - c0
        self._sim_stepped += n * dt
        if ticked:
            for fn in self.on_tick:
                fn(self)

    def _set_digging(self, passes: int, centre: NDArray[np.float64], radius: float,
                     rim: float) -> None:
        """The no-slip passes for the next tick: ``passes`` (the food's
        ``noslip_iterations_digging``) while the utensil's tip is inside the container (within
        ``radius`` of its axis through ``centre``, below its ``rim``), the food's
        ``noslip_iterations`` elsewhere. No bottom bound: a spoon's tip site is the floor's
        plane at the rim's far end, outside the metal, so it reads below the container's
        floor while a spoon tilted tip-down rests on it."""
        p = self.data.site_xpos[self.index.tip_site]
        inside = p[2] < rim and math.hypot(p[0] - centre[0], p[1] - centre[1]) < radius
        self.model.opt.noslip_iterations = passes if inside else self._passes

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
    def strands(self) -> bool:
        """The food is strands (noodles): an item may hang from the utensil onto a surface."""
        return self.food is not None and isinstance(self.params.food(self.food), Strands)

    def close(self) -> None:
        """Free what the world holds beside MuJoCo (the liquids' solvers); idempotent."""
        if self.bowl is not None:
            self.bowl.close()
        if self.placement.liquid is not None:
            self.placement.liquid.close()

    def report(self, measure_ft: bool = False) -> WorldReport:
        """The world's report now (``measure_ft``: include the F/T-measured mass, when the
        sensor is oriented as at its tare — see
        :meth:`Weighing.comparable <articutool.sim.weighing.Weighing.comparable>`)."""
        return WorldReport(
            t=round(self.time, 4), food=self.food, utensil=self.utensil,
            masses_g=self.ledger.masses_g(),
            total_g=self.ledger.total_g(),
            spills=list(self.ledger.spills),
            ft_mass_g=(self.weighing.ft_mass_g() if measure_ft and self.weighing.comparable()
                       else None),
            realtime_factor=self.realtime_factor,
            arm_tracking_error_rad=self.arm_tracking_error,
        )
