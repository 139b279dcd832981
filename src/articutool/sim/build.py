"""The parts of a feeding world, built and checked before anything steps.

A :class:`WorldConfig` is what a world is built from (food, utensil, spec, scene, physics
parameters, seed, start angles, sensor noise, a load to place by hand, the mouth), every field
checked once when it is made. :func:`build_parts` builds the world's ``MjSpec`` from it
(:mod:`articutool.sim.world_spec`), compiles it, indexes its joints, actuators, sensors and sites
(:class:`WorldIndex`), puts the arm and the wrist at their start, and builds the food ledger,
the MuJoCo-backed drivers and the tool's runtime on them. Nothing here steps the physics:
:meth:`articutool.sim.world.FeedingWorld.build` wires the parts into a world, then settles it
(restoring a settled pile from a :class:`SettleCache` when it has one), starts the tool and
tares the F/T sensor.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.arm.scene import Scene
from articutool.sim.ledger import FoodLedger
from articutool.sim.mj_drivers import MjFTDriver, MjImuDriver, MjMotorDriver
from articutool.sim.params import PhysicsParams
from articutool.sim.placement import (
    capacity_bound_reason,
    load_supply_g,
    utensil_capacity_bound_g,
)
from articutool.sim.world_spec import (
    FT_SITE,
    IMU_SITE,
    WorldLayout,
    build_world_spec,
    tip_site_name,
)
from articutool.spec import Spec, load_spec
from articutool.tool.drivers.motor_model import MotorPlant
from articutool.tool.runtime import ToolRuntime

__all__ = ["SettleCache", "SettledState", "WorldConfig", "WorldIndex", "WorldParts", "build_parts"]

# What a settle leaves: every byte of mjData, and the stepping loop's own state (the wrist's
# velocity-loop integrals, the arm's worst tracking error, the physics steps taken).
SettledState = tuple[mujoco.MjData, NDArray[np.float64], float, int]


class SettleCache:
    """Settled worlds by (model, start state), restored instead of settled again: the
    same model and start state settle to the same state, so a copy of every byte of
    ``mjData`` (sleep state, contacts and the solver's warm start included) and the world's
    own servo state is the state a fresh settle makes, to the bit
    (``tests/test_sim_speed.py``). Whoever runs many worlds owns one (the experiments'
    runner, one per worker process: an experiment's conditions share a repeat's seed, so
    they share its settled pile); a world built without one settles afresh.

    It keeps the ``keep`` most recently used states (one is a full ``mjData``). The worlds
    of several threads (trials in one Dask worker) may share it: a state taken is another
    thread's no more until it is put back."""

    def __init__(self, keep: int = 4) -> None:
        if keep < 1:
            raise ValueError(f"keep must be >= 1; got {keep}")
        self.keep = keep
        self._states: dict[str, SettledState] = {}
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._states)

    def take(self, key: str) -> SettledState | None:
        """The state settled under ``key`` (removed until :meth:`put` back), or None."""
        with self._lock:
            return self._states.pop(key, None)

    def put(self, key: str, state: SettledState) -> None:
        """Keep ``state`` under ``key`` as the most recently used; forget the oldest beyond
        ``keep``."""
        with self._lock:
            self._states.pop(key, None)
            self._states[key] = state
            while len(self._states) > self.keep:
                self._states.pop(next(iter(self._states)))


@dataclass(frozen=True)
class WorldIndex:
    """Where the world's joints, actuators, sensors and sites sit in the compiled model."""

    arm_q: NDArray[np.int64]  # the arm joints' qpos addresses
    arm_v: NDArray[np.int64]  # … and dof addresses
    wrist_q: NDArray[np.int64]  # the wrist joints' [pitch, roll] qpos addresses
    wrist_v: NDArray[np.int64]  # … and dof addresses
    act_pos: NDArray[np.int64]  # the arm servos' position actuators
    act_vel: NDArray[np.int64]  # … and velocity actuators
    act_wrist: NDArray[np.int64]  # the wrist motors' torque actuators
    wrist_range: NDArray[np.float64]  # (2, 2) the wrist joints' ranges (rad)
    s_acc: int  # sensordata addresses: IMU accelerometer, gyro, F/T force, torque
    s_gyro: int
    s_force: int
    s_torque: int
    tip_site: int  # the utensil tip's site
    ft_site: int  # the F/T sensor's site
    imu_site: int  # the IMU's site (the tool base F0)

    @classmethod
    def of(cls, m: mujoco.MjModel, layout: WorldLayout, utensil: str) -> WorldIndex:
        """The index of ``m`` built from ``layout`` with ``utensil`` on the tool."""
        arm, wrist = layout.arm_joints, layout.wrist_joints
        return cls(
            arm_q=np.array([m.joint(n).qposadr[0] for n in arm]),
            arm_v=np.array([m.joint(n).dofadr[0] for n in arm]),
            wrist_q=np.array([m.joint(n).qposadr[0] for n in wrist]),
            wrist_v=np.array([m.joint(n).dofadr[0] for n in wrist]),
            act_pos=np.array([m.actuator(f"{n}/pos").id for n in arm]),
            act_vel=np.array([m.actuator(f"{n}/vel").id for n in arm]),
            act_wrist=np.array([m.actuator(f"{n}/motor").id for n in wrist]),
            wrist_range=np.array([m.jnt_range[m.joint(n).id] for n in wrist]),
            s_acc=m.sensor("imu_accel").adr[0], s_gyro=m.sensor("imu_gyro").adr[0],
            s_force=m.sensor("ft_force").adr[0], s_torque=m.sensor("ft_torque").adr[0],
            tip_site=m.site(tip_site_name(utensil)).id, ft_site=m.site(FT_SITE).id,
            imu_site=m.site(IMU_SITE).id)


@dataclass(frozen=True)
class WorldParts:
    """A world's parts, built and wired to one another, its physics not yet stepped."""

    config: WorldConfig
    layout: WorldLayout
    model: mujoco.MjModel
    data: mujoco.MjData  # the arm and the wrist at their start, forward kinematics done
    index: WorldIndex
    ledger: FoodLedger
    motors: MjMotorDriver
    imu: MjImuDriver
    ft: MjFTDriver
    tool: ToolRuntime  # on the simulation clock, not yet opened


def _start(spec: Spec, q_arm: ArrayLike | None,
           q_wrist: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The arm's and the wrist's start angles, checked."""
    q0 = np.asarray(spec.arm.configuration("Resting") if q_arm is None else q_arm, dtype=float)
    if q0.shape != (6,) or not np.isfinite(q0).all():
        raise ValueError(f"q_arm must be 6 finite joint angles; got {q_arm!r}")
    lo, hi = spec.arm.lower, spec.arm.upper
    bad = np.flatnonzero((q0 < lo) | (q0 > hi))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"q_arm[{i}] = {q0[i]:.4g} rad is outside the joint's range "
                         f"[{lo[i]:.4g}, {hi[i]:.4g}]")
    qw = np.asarray(q_wrist, dtype=float)
    if qw.shape != (2,) or not np.isfinite(qw).all():
        raise ValueError(f"q_wrist must be 2 finite angles [pitch, roll]; got {q_wrist!r}")
    return q0, qw


@dataclass(frozen=True)
class WorldConfig:
    """What a feeding world is built from, checked once when made: a bad field raises
    ``ValueError`` naming it and its range (an unknown food: ``PhysicsError`` naming the
    allowed ones). Defaults are resolved on creation, so every field holds what the world
    uses (``utensil``, ``spec``, ``scene``, ``params``, ``q_arm`` are never ``None``).

    Fields:
        food: a food of ``physics.toml`` (``None``: no food).
        utensil: which utensil the tool carries (default: the food's utensil).
        spec, scene, params: hardware spec, scene and physics parameters (packaged
            defaults).
        seed: food placement, sensor noise and gyro bias; same seed, same result.
        q_arm: the arm's start configuration (default: the spec's ``Resting``).
        q_wrist: the wrist's start angles [pitch, roll] (rad).
        noise: sensor noise on (IMU, F/T); the gyro bias is on either way unless given.
        gyro_bias: rad/s (3,); default drawn from ±1 °/s per axis with the seed.
        load_g: instead of filling the food's container, hold this many grams of it ready
            to be placed on the utensil with ``world.placement.place`` (the thesis' Exp.
            2b/2c protocol: a tared utensil loaded by hand).
        mouth: food entering the scene's ``mouth`` region is eaten (a bite); ``False`` for
            protocols in which nobody eats and the experimenter weighs the utensil at the
            goal (Exp. 2b, 2c).
    """

    food: str | None = "pecans"
    utensil: str | None = None
    # The packaged defaults, loaded when a config is made (not when this class is defined).
    spec: Spec = field(default_factory=lambda: load_spec())
    scene: Scene = field(default_factory=lambda: Scene.load())
    params: PhysicsParams = field(default_factory=lambda: PhysicsParams.load())
    seed: int = 0
    q_arm: tuple[float, ...] | None = None
    q_wrist: tuple[float, ...] = (0.0, 0.0)
    noise: bool = True
    gyro_bias: tuple[float, ...] | None = None
    load_g: float | None = None
    mouth: bool = True

    def __post_init__(self) -> None:
        def resolve(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        # An explicit None is the packaged default too.
        spec = self.spec if self.spec is not None else load_spec()
        params = self.params if self.params is not None else PhysicsParams.load()
        resolve("spec", spec)
        resolve("scene", self.scene if self.scene is not None else Scene.load())
        resolve("params", params)
        food, seed, load_g = self.food, self.seed, self.load_g
        if food is not None:
            params.food(food)  # unknown food → PhysicsError naming the allowed ones
        utensil = self.utensil or (params.food(food).utensil if food else "spoon")
        resolve("utensil", utensil)
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
        resolve("seed", int(seed))
        if load_g is not None and not (math.isfinite(load_g) and load_g > 0):
            raise ValueError(f"load_g must be a finite mass > 0 g; got {load_g}")
        if load_g is not None and food is None:
            raise ValueError("load_g needs a food")
        if load_g is not None and load_g > (
                most := utensil_capacity_bound_g(spec, params, food or "", utensil)):
            why = capacity_bound_reason(params.food(food or ""))
            raise ValueError(f"load_g must be in (0, {most:.2f}] g: the most the "
                             f"{utensil} can hold of {food} ({why}); got {load_g:g}")
        q0, qw = _start(spec, self.q_arm, self.q_wrist)
        resolve("q_arm", tuple(float(v) for v in q0))
        resolve("q_wrist", tuple(float(v) for v in qw))
        if self.gyro_bias is not None:
            resolve("gyro_bias", tuple(float(v) for v in np.asarray(self.gyro_bias, dtype=float)))


def build_parts(config: WorldConfig) -> WorldParts:
    """The parts of the world ``config`` describes (checked when it was made)."""
    c = config
    spec, scene, params, food, utensil, seed = (c.spec, c.scene, c.params, c.food,
                                                str(c.utensil), c.seed)
    q0, qw = np.array(c.q_arm, dtype=float), np.array(c.q_wrist, dtype=float)
    layout = build_world_spec(spec, scene, params, utensil, food, seed,
                              load_supply_g(params, food, c.load_g))
    m = layout.spec.compile()
    d = mujoco.MjData(m)
    period = spec.wrist.period
    dt = float(m.opt.timestep)
    if abs(round(period / dt) * dt - period) > 1e-9:
        raise ValueError(f"world.timestep {dt} s must divide the loop period {period} s")
    rng = np.random.default_rng(seed + 1_000_003)
    ix = WorldIndex.of(m, layout, utensil)
    ledger = FoodLedger(m, d, layout, scene, params.world.spill_dwell_s, period, mouth=c.mouth)
    d.qpos[ix.arm_q] = q0
    d.qpos[ix.wrist_q] = qw
    mujoco.mj_forward(m, d)
    bias = (rng.uniform(-1.0, 1.0, 3) * math.radians(1.0) if c.gyro_bias is None
            else np.array(c.gyro_bias, dtype=float))
    plant = MotorPlant(position=lambda: d.qpos[ix.wrist_q].copy(),
                       velocity=lambda: d.qvel[ix.wrist_v].copy(),
                       input_voltage=lambda: spec.motors.supply_v,
                       temperature=lambda: 35.0, stamp=lambda: float(d.time))
    motors = MjMotorDriver(spec, plant, ix.wrist_range)
    imu = MjImuDriver(spec, bias, c.noise, rng)
    ft = MjFTDriver(spec, c.noise, rng)
    tool = ToolRuntime(spec, motors, imu, ft, clock=lambda: float(d.time))
    return WorldParts(config=c, layout=layout, model=m, data=d, index=ix, ledger=ledger,
                      motors=motors, imu=imu, ft=ft, tool=tool)
