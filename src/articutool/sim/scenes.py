"""Short scripted scenes in the physics world: scoop, carry, tilt (``articutool sim``).

- **scoop** (a fork skewers instead, see :func:`skewer`): from above the food's container,
  the arm (wrist held still, as a rigid spoon) drives the utensil tip steeply (60°) down
  into the food, drags it through, turns it level while rising out of the bowl and lifts
  it; with leveling on, the tool then levels. A liquid runs out of the soup spoon during
  the rise (it is level only once out of the bowl): this scoop acquires no water.
- **carry**: a scoop, then a fast arm motion — the last arm joint (the hand's axis) turns at
  its speed limit until a locked utensil would tilt 40° — and a 1.5 s hold. A leveling wrist
  turns against it; a locked one does not.
- **tilt**: a scoop, then the tool's own TILT primitive (roll to 45° at 0.5 rad/s, hold 1 s,
  return), which pours out what does not stay.

Arm motions are Cartesian paths of the tip (:mod:`articutool.planning.tip_paths`: the
Pinocchio IK for the arm joints, the wrist at its present angles, timed so that no arm joint
exceeds its speed limit), run through the arm's servos (never teleported).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from articutool.arm.model import ArmModel
from articutool.arm.scene import SCOOP_HEADING, Cylinder
from articutool.planning.tip_paths import PathError, cartesian_path, first_ik, lift_trajectory
from articutool.sim.twirl import max_twirl_turns
from articutool.sim.world import FeedingWorld, WorldReport
from articutool.tool.api import Mode

__all__ = [
    "SCRIPTS",
    "SKEWER_TIP_ABOVE_FLOOR_M",
    "ScriptError",
    "acquire",
    "max_twirl_turns",
    "run_script",
    "scoop",
    "skewer",
]

SCRIPTS = ("scoop", "carry", "tilt")
_Z = np.array([0.0, 0.0, 1.0])
# The scripted skewer presses the fork until its tip is this far above the bowl's floor.
SKEWER_TIP_ABOVE_FLOOR_M = 0.002


class ScriptError(PathError):
    """A scripted scene could not be made (no container, a primitive refused); a tip path that
    cannot be made raises :class:`~articutool.planning.tip_paths.PathError`, its base."""


def _wrist(world: FeedingWorld) -> NDArray[np.float64]:
    """The wrist's angles for the kinematic model: roll wrapped to (−π, π] (after a twirl the
    motor has turned whole turns; the utensil's pose is the same)."""
    q = world.wrist_q
    q[1] = math.remainder(q[1], 2 * math.pi)
    return q


def scoop(world: FeedingWorld, level: bool = True) -> None:
    """Acquire from the food's container and lift (see module doc)."""
    box = world.scene.get(world.layout.container or "bowl")
    if not isinstance(box, Cylinder) or box.container_wall is None:
        raise ScriptError("scoop needs the food's container (an open bowl)")
    model = ArmModel(world.spec, world.utensil, 8, world.scene)
    h = SCOOP_HEADING
    c = box.inner_floor()
    inner = box.radius - box.container_wall
    back = c - h * 0.55 * inner
    rad = math.radians
    # Steep entry and drag (the handle clears the rim), then turn level while rising; every
    # pose is collision-free for the arm and wrist in the planning model (the utensil may
    # touch the bowl). The lip drags 3-4 mm above the floor, under the lowest layer: at
    # 10-12 mm it met flat pecan pieces (5-8 mm thick) edge-on mid-layer and pushed them —
    # the pieces it touched sat on its rim or under its dish, never in it (measured, seed 0).
    pts = [
        (back + _Z * 0.12, rad(60), 0.15),
        (back + _Z * 0.04, rad(60), 0.06),
        (c - h * 0.1 * inner + _Z * 0.003, rad(60), 0.03),
        (c + h * 0.3 * inner + _Z * 0.004, rad(50), 0.03),
        (c + h * 0.4 * inner + _Z * 0.05, rad(30), 0.03),
        (c + h * 0.4 * inner + _Z * 0.075, rad(0), 0.03),
        (c + h * 0.4 * inner + _Z * 0.16, rad(0), 0.06),
    ]
    # Level the empty utensil and tare the F/T sensor there, as one would before a bite (the
    # F/T then weighs the load when level); the wrist then holds these angles (DISABLED).
    world.tool.set_mode(Mode.LEVELING)
    world.run(1.0)
    world.tool.set_mode(Mode.DISABLED)
    world.weighing.tare(0.3)
    # Get above the start first (a free joint motion), then the Cartesian scoop.
    q0 = first_ik(model, np.concatenate([world.arm_q, _wrist(world)]), pts[0][0], pts[0][1])
    world.move_arm(q0[:6])
    world.follow_arm(cartesian_path(model, q0, pts), settle_s=0.3)
    # Leveling starts out of the food: engaged in it, the wrist's fast pitch (up to its
    # 4 rad/s) swings the tip ~12 cm up through the pile and flings the load (measured).
    if level:
        ok, msg = world.tool.set_mode(Mode.LEVELING)
        if not ok:
            raise ScriptError(f"the tool refused LEVELING: {msg}")
    world.run(1.0)


def base_tilt_motion(world: FeedingWorld, tilt_deg: float = 40.0) -> NDArray[np.float64]:
    """Arm configuration that tilts a locked utensil by ``tilt_deg`` from where it is now,
    by turning the last arm joint (the hand's axis) as little as needed."""
    model = ArmModel(world.spec, world.utensil, 8, world.scene)
    q = world.q
    up0 = model.tip_pose(q)[:3, 1]
    for step in np.radians(np.arange(1.0, 120.0, 0.5)):
        for sign in (1.0, -1.0):
            qk = q.copy()
            qk[5] += sign * step
            if not world.spec.arm.lower[5] <= qk[5] <= world.spec.arm.upper[5]:
                continue
            up = model.tip_pose(qk)[:3, 1]
            if math.degrees(math.acos(np.clip(up @ up0, -1.0, 1.0))) >= tilt_deg:
                return qk[:6]
    raise ScriptError(f"turning the hand cannot tilt the utensil by {tilt_deg}°")


def skewer(world: FeedingWorld, level: bool = True, twirl_turns: float | None = None,
           tines_up: bool = True, on_phase: Callable[[str], None] | None = None,
           prewind_turns: float = 0.0) -> None:
    """The fork's acquisition (thesis §4.4, noodles): the fork, pointing 60° down, goes into
    the food's container, pressed through the pile to 2 mm above its floor (as one presses a
    fork to the plate to twirl), TWIRL_CW turns it ``twirl_turns`` times about the tool's roll
    axis at 3 rad/s (0: a still fork; default :func:`max_twirl_turns`), it rises 3.8 cm
    turning its tines up (60° → 0° below the horizon; ``tines_up`` off: still 60° down), the
    tool levels (unless ``level`` is off), and the arm lifts 12 cm. ``on_phase`` is called
    after each phase with its name: "in", "twirled", "risen", "levelled", "lifted".
    ``prewind_turns``: TWIRL_CCW that many turns in the air first (the thesis' twirl before
    insertion), which frees as much roll budget for the twirl inside the food."""
    box = world.scene.get(world.layout.container or "bowl")
    if not isinstance(box, Cylinder) or box.container_wall is None:
        raise ScriptError("skewer needs the food's container (an open bowl)")
    turns = max_twirl_turns(world.spec) if twirl_turns is None else twirl_turns
    phase = on_phase or (lambda name: None)
    model = ArmModel(world.spec, world.utensil, 8, world.scene)
    world.tool.set_mode(Mode.LEVELING)
    world.run(1.0)
    world.tool.set_mode(Mode.DISABLED)
    world.weighing.tare(0.2)
    if prewind_turns > 0:
        ok, msg = world.tool.start_primitive("TWIRL_CCW", [prewind_turns, 3.0])
        if not ok:
            raise ScriptError(f"the tool refused TWIRL_CCW: {msg}")
        world.run_until(lambda: world.tool.mode != Mode.PRIMITIVE, 30.0)
    c = box.inner_floor()
    a = math.radians(60.0)
    pts = [(c + _Z * 0.12, a, 0.1), (c + _Z * 0.03, a, 0.05),
           (c + _Z * SKEWER_TIP_ABOVE_FLOOR_M, a, 0.02)]
    q0 = first_ik(model, np.concatenate([world.arm_q, _wrist(world)]), pts[0][0], a)
    world.move_arm(q0[:6])
    world.follow_arm(cartesian_path(model, q0, pts), settle_s=0.2)
    phase("in")
    if turns > 0:
        ok, msg = world.tool.start_primitive("TWIRL_CW", [turns, 3.0])
        if not ok:
            raise ScriptError(f"the tool refused TWIRL_CW: {msg}")
        world.run_until(lambda: world.tool.mode != Mode.PRIMITIVE, 30.0)
    phase("twirled")
    # Tines up while rising, as one turns a fork up under a twirled bite: a wrap on tines
    # still pointing down slides off their tips (measured: 0 g for seed 5000 at 60°).
    q = np.concatenate([world.arm_q, _wrist(world)])
    rise = ([(c + _Z * 0.012, math.radians(30.0), 0.02), (c + _Z * 0.04, 0.0, 0.02)]
            if tines_up else [(c + _Z * 0.04, a, 0.02)])
    world.follow_arm(cartesian_path(model, q, [(pts[-1][0], a, 0.02), *rise]), settle_s=0.2)
    phase("risen")
    if level:
        world.tool.set_mode(Mode.LEVELING)
    world.run(1.0)
    phase("levelled")
    _lift(world, model)  # the tool base goes straight up; the wrist keeps the fork level
    world.run(1.0)
    phase("lifted")


def _lift(world: FeedingWorld, model: ArmModel, height: float = 0.12,
          speed_scale: float = 0.3) -> None:
    """Lift the tool base straight up by ``height`` (its orientation kept; the wrist does what
    its mode says), slowly: the arm's limits scaled by ``speed_scale``."""
    world.follow_arm(lift_trajectory(model, np.concatenate([world.arm_q, _wrist(world)]),
                                     height, speed_scale), settle_s=0.5)


def load(world: FeedingWorld, level: bool = True) -> None:
    """The thesis' Exp. 2b/2c protocol instead of an acquisition: level the empty utensil,
    tare the F/T sensor, and place the world's ``load_g`` on it; with ``level`` off the wrist
    then stays locked (DISABLED) at those angles."""
    world.tool.set_mode(Mode.LEVELING)
    world.run(1.0)
    if not level:
        world.tool.set_mode(Mode.DISABLED)
    world.weighing.tare(0.3)
    world.placement.place(settle_s=1.0)


def acquire(world: FeedingWorld, level: bool = True, twirl_turns: float | None = None) -> None:
    """The utensil's acquisition: a placed load if the world holds one (``load_g``), else a
    twirling skewer with a fork (``twirl_turns``, see :func:`skewer`), a scoop with a spoon."""
    if world.load_g is not None:
        load(world, level)
    elif world.spec.utensil(world.utensil).physics.kind == "fork":
        skewer(world, level, twirl_turns)
    else:
        scoop(world, level)


def carry(world: FeedingWorld, level: bool = True, twirl_turns: float | None = None) -> None:
    """Scoop, then turn the arm's last joint at its speed limit until a locked utensil would
    tilt 40°, and hold 1.5 s."""
    acquire(world, level, twirl_turns)
    world.move_arm(base_tilt_motion(world, 40.0), wait=True)
    world.run(1.5)


def tilt(world: FeedingWorld, level: bool = True, twirl_turns: float | None = None) -> None:
    """Scoop, then the tool's TILT primitive: roll 45° at 0.5 rad/s, hold 1 s, return."""
    acquire(world, level, twirl_turns)
    world.tool.set_mode(Mode.DISABLED)
    ok, msg = world.tool.start_primitive("TILT", [math.radians(45.0), 0.5, 1.0])
    if not ok:
        raise ScriptError(f"the tool refused TILT: {msg}")
    world.run_until(lambda: world.tool.mode != Mode.PRIMITIVE, 20.0)
    if level:
        world.tool.set_mode(Mode.LEVELING)
    world.run(1.0)


def run_script(world: FeedingWorld, script: str, level: bool = True,
               twirl_turns: float | None = None) -> WorldReport:
    """Run a named scene and return the world's report (with the F/T-measured mass at rest);
    ``twirl_turns``: the fork's twirl (see :func:`skewer`)."""
    fn = {"scoop": acquire, "carry": carry, "tilt": tilt}.get(script)
    if fn is None:
        raise ValueError(f"script must be one of {SCRIPTS}; got {script!r}")
    fn(world, level, twirl_turns)
    return world.report(measure_ft=True)
