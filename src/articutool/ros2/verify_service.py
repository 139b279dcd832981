"""Plan-then-verify as a ROS 2 service: ``VerifyTrajectory`` requests → the verifier → replies.

:func:`answer` takes a request (any object with the ``VerifyTrajectory`` request's fields: an
rclpy message or a test's stand-in) and returns the reply's fields as a dict; it never
raises for a bad request. A request that cannot be verified as given — no points, unknown or
missing arm joints, a NaN, times that do not increase, an unknown utensil, a step or wrist
start out of range, a negative or non-finite load — is answered ``feasible=false``,
``reason="bad_request"`` and a message naming the field, never assumed feasible.

The verifier is :func:`articutool.verify.verifier.verify_trajectory` (dense sampling, arm
position and velocity limits, leveling solutions, jumps, Eq. 4.7 rates). With a load
(``food`` and ``load_g`` > 0) it also predicts what the load spills along the executed motion
(the leveling wrist's trajectory it computed; :mod:`articutool.verify.food`): a transport
predicted to spill is answered ``feasible=false``, ``reason="spill"``, with
``spill_checked=true`` and ``predicted_spill_g``; a load the model cannot judge (an unknown
food, more than the utensil holds) is a bad request naming the field.

:class:`VerifyServer` serves it on the node: the verifier runs on a lane of its own, so a
verification never holds an executor thread or the tool's commands.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from articutool.food.definitions import FoodDefinition, load_food_definitions
from articutool.food.loads import FoodLoad, LoadError, named_load
from articutool.ros2.intake import create_draining_service
from articutool.ros2.lanes import WorkLane
from articutool.ros2.serving import Side, submit
from articutool.trajectory import JointTrajectory, TrajectoryError

__all__ = ["BadRequestError", "Verifier", "VerifyServer", "trajectory_from_ros"]

_log = logging.getLogger(__name__)


class BadRequestError(ValueError):
    """A request field that cannot be verified; the message names the field."""


def _duration(d: Any) -> float:
    return float(d.sec) + float(d.nanosec) * 1e-9


def trajectory_from_ros(msg: Any, field: str = "trajectory") -> JointTrajectory:
    """A ``trajectory_msgs/JointTrajectory`` (any object with its fields) → JointTrajectory.

    Empty velocities become zeros. Raises :class:`BadRequestError` naming the field.
    """
    names = [str(n) for n in msg.joint_names]
    points = list(msg.points)
    if not points:
        raise BadRequestError(f"{field}.points is empty: there is nothing to verify")
    if not names:
        raise BadRequestError(f"{field}.joint_names is empty")
    n = len(names)
    t, q, v = [], [], []
    for i, p in enumerate(points):
        pos = np.asarray(p.positions, dtype=np.float64)
        vel = np.asarray(p.velocities, dtype=np.float64)
        if pos.size != n:
            raise BadRequestError(f"{field}.points[{i}].positions has {pos.size} values for "
                             f"{n} joints")
        if vel.size == 0:
            vel = np.zeros(n)
        elif vel.size != n:
            raise BadRequestError(f"{field}.points[{i}].velocities has {vel.size} values for "
                             f"{n} joints (give {n} or none)")
        if not (np.isfinite(pos).all() and np.isfinite(vel).all()):
            raise BadRequestError(f"{field}.points[{i}] holds a NaN or infinite value")
        t.append(_duration(p.time_from_start))
        q.append(pos)
        v.append(vel)
    try:
        return JointTrajectory(tuple(names), np.array(t), np.array(q), np.array(v))
    except TrajectoryError as err:
        raise BadRequestError(f"{field}: {err}") from None


class Verifier:
    """Answers ``VerifyTrajectory`` requests with one spec and the foods' definitions
    (``foods``; default: the packaged ones, read once); arm models are built once per
    utensil (a Pinocchio model takes ~0.1 s) and shared by the calls."""

    def __init__(self, spec: Any, default_utensil: str, wrist_joint_names: tuple[str, str],
                 foods: Mapping[str, FoodDefinition] | None = None):
        self.spec = spec
        self.foods = dict(foods) if foods is not None else load_food_definitions()
        if default_utensil not in spec.utensils:
            raise ValueError(f"utensil must be one of {sorted(spec.utensils)}; got "
                             f"{default_utensil!r}")
        self.default_utensil = default_utensil
        self.wrist_joint_names = tuple(wrist_joint_names)
        self._models: dict[str, Any] = {}
        self._lock = threading.Lock()

    def _model(self, utensil: str) -> Any:
        from articutool.arm.model import ArmModel
        with self._lock:
            if utensil not in self._models:
                self._models[utensil] = ArmModel(self.spec, utensil=utensil)
            return self._models[utensil]

    def _checked(self, req: Any, current_wrist: tuple[float, float] | None
                 ) -> tuple[JointTrajectory, str, float, np.ndarray, FoodLoad | None]:
        utensil = str(req.utensil) or self.default_utensil
        if utensil not in self.spec.utensils:
            raise BadRequestError(f"utensil must be one of {sorted(self.spec.utensils)} (or empty "
                             f"for {self.default_utensil!r}); got {utensil!r}")
        step = float(req.max_step_deg)
        if step == 0.0:
            step = 1.0
        if not (math.isfinite(step) and 0.0 < step <= 45.0):
            raise BadRequestError(f"max_step_deg must be in (0, 45] degrees (0 for 1); got {step}")
        start = np.asarray(req.wrist_start, dtype=np.float64)
        if start.size == 0:
            start = np.asarray(current_wrist if current_wrist is not None else (0.0, 0.0))
        if start.shape != (2,) or not np.isfinite(start).all():
            raise BadRequestError(f"wrist_start must be empty or two finite angles [pitch, roll] "
                             f"(rad); got {list(start)}")
        food, load = str(req.food), float(req.load_g)
        if not (math.isfinite(load) and load >= 0.0):
            raise BadRequestError(f"load_g must be a finite mass >= 0 (g); got {load}")
        if load > 0.0 and not food:
            raise BadRequestError("food must name the load's food when load_g > 0")
        # an unknown food is refused before any verification
        food_load = named_load(food, load, self.foods, "food") if load > 0.0 else None
        traj = trajectory_from_ros(req.trajectory)
        arm = self.spec.arm.joint_names
        missing = [n for n in arm if n not in traj.joint_names]
        extra = [n for n in traj.joint_names if n not in arm]
        if missing or extra:
            raise BadRequestError(f"trajectory.joint_names must be the arm's {len(arm)} joints "
                             f"{list(arm)} in any order; missing {missing}, unknown {extra}")
        return traj, utensil, step, start, food_load

    def answer(self, req: Any, current_wrist: tuple[float, float] | None = None
               ) -> dict[str, Any]:
        """The reply's fields for ``req`` (``wrist_trajectory`` as a JointTrajectory or
        None); ``current_wrist`` is the tool's position, the default wrist start."""
        from articutool.verify.verifier import verify_trajectory
        try:
            traj, utensil, step, start, food_load = self._checked(req, current_wrist)
            rep = verify_trajectory(traj, self._model(utensil), self.spec, max_step_deg=step,
                                    q_wrist_start=start, utensil=utensil, load=food_load)
        except (BadRequestError, TrajectoryError, LoadError) as err:
            return _refusal(str(err))
        message = rep.message
        checked = rep.food is not None
        wt = rep.wrist_trajectory
        if wt is not None:
            wt = JointTrajectory(self.wrist_joint_names, wt.times, wt.positions, wt.velocities)
        return {
            "feasible": bool(rep.feasible), "reason": rep.reason, "message": message,
            "first_failure_time": (-1.0 if rep.first_failure_time is None
                                   else float(rep.first_failure_time)),
            "velocity_margin": float(rep.velocity_margin),
            "max_required_velocity": [float(x) for x in rep.max_required_velocity],
            "samples_checked": int(rep.samples_checked),
            "wrist_trajectory": wt, "spill_checked": checked,
            "predicted_spill_g": (float(rep.food.prediction.spilled_g) if checked
                                  else math.nan),
        }


def _refusal(message: str) -> dict[str, Any]:
    return {"feasible": False, "reason": "bad_request", "message": message,
            "first_failure_time": -1.0, "velocity_margin": math.nan,
            "max_required_velocity": [], "samples_checked": 0, "wrist_trajectory": None,
            "spill_checked": False, "predicted_spill_g": math.nan}


class VerifyServer:
    """``VerifyTrajectory`` on ``side`` (the main node), answered by ``verifier`` on a lane of
    its own (one thread, four waiting; a full lane answers ``reason="busy"`` at once);
    ``wrist()`` is the tool's present position (None without one), the default wrist start.
    The service drains its queue (:mod:`articutool.ros2.intake`)."""

    def __init__(self, verifier: Verifier, side: Side, name: str,
                 wrist: Callable[[], tuple[float, float] | None],
                 counters: dict[str, int]) -> None:
        from articutool_interfaces.srv import VerifyTrajectory

        self._verifier, self._side, self._wrist, self._counters = verifier, side, wrist, counters
        self._lane = WorkLane("ros2-verify", threads=1, capacity=4)
        create_draining_service(side.node, VerifyTrajectory, name, self._start_verify,
                                qos_profile=side.qos, callback_group=side.group)

    def close(self) -> None:
        self._lane.close()

    def _start_verify(self, request: Any, response: Any) -> Any:
        verifier, wrist = self._verifier, self._wrist()
        future = submit(self._lane, lambda: verifier.answer(request, wrist), self._side.wake,
                        self._counters)
        if future is None:
            return _fill_verify(response, {
                "feasible": False, "reason": "busy", "first_failure_time": -1.0,
                "message": "refused: busy (verifications waiting); try again",
                "velocity_margin": math.nan, "predicted_spill_g": math.nan})
        return self._finish_verify(future, response)

    @staticmethod
    async def _finish_verify(future: Any, response: Any) -> Any:
        try:
            out = await future
        except Exception as err:
            _log.exception("verify_trajectory failed")
            out = {"feasible": False, "reason": "error", "first_failure_time": -1.0,
                   "message": f"internal error: {type(err).__name__}: {err}",
                   "velocity_margin": math.nan, "predicted_spill_g": math.nan}
        return _fill_verify(response, out)


def _ros_trajectory(traj: Any, out: Any) -> Any:
    """articutool JointTrajectory → the given ``trajectory_msgs/JointTrajectory`` message."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectoryPoint

    out.joint_names = list(traj.joint_names)
    pts = []
    for t, q, v in zip(traj.times, traj.positions, traj.velocities, strict=True):
        sec = math.floor(t)
        pts.append(JointTrajectoryPoint(
            positions=np.asarray(q, dtype=float).tolist(),
            velocities=np.asarray(v, dtype=float).tolist(),
            time_from_start=Duration(sec=int(sec),
                                     nanosec=min(round((t - sec) * 1e9), 999_999_999))))
    out.points = pts
    return out


def _fill_verify(response: Any, out: dict[str, Any]) -> Any:
    """A VerifyTrajectory response from the verifier's answer."""
    for key in ("feasible", "reason", "message", "first_failure_time", "velocity_margin",
                "samples_checked", "spill_checked", "predicted_spill_g",
                "max_required_velocity"):
        if key in out:
            setattr(response, key, out[key])
    wt = out.get("wrist_trajectory")
    if wt is not None:
        response.wrist_trajectory = _ros_trajectory(wt, response.wrist_trajectory)
    return response
