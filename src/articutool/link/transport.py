"""Transport interface and the ROS 2 → Zenoh name mapping of the Articutool link.

The tool server and the PC client speak to a :class:`Transport` only, so they do not depend on
Zenoh: :class:`~articutool.link.zenoh_transport.ZenohTransport` is the real link and
:class:`~articutool.link.memory_transport.MemoryTransport` an in-process one for unit tests.

Key-expression mapping (after rmw_zenoh's design document, ``ros2/rmw_zenoh`` docs/design.md,
"Topic and Service name mapping to Zenoh key expressions")::

    <domain_id>/<fully qualified name without leading '/'>/<DDS type name>/<RIHS01 type hash>

e.g. ``0/articutool/wrist-1/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e…``:
every name is under ``/<namespace>/<tool_id>`` (default ``/articutool/default``), so a client
addresses one tool by its identity. Below, ``/articutool/`` stands for that prefix.
Topics are Zenoh publishers/subscribers; services are Zenoh queryables answered by ``get``.
Payloads are ROS 2 CDR with the 4-byte encapsulation header (see ``messages``).

=====================================  ==========================================  =========
ROS 2 name                             type (DDS name ``pkg::kind::dds_::Name_``)  kind
=====================================  ==========================================  =========
/articutool/set_orientation_control    articutool_interfaces/srv/SetOrientation…   service
/articutool/execute_primitive/         articutool_interfaces/action/ExecuteArtic…  action:
  _action/send_goal                    …ExecuteArticutoolPrimitive_SendGoal        service
  _action/get_result                   …ExecuteArticutoolPrimitive_GetResult       service
  _action/cancel_goal                  action_msgs/srv/CancelGoal                  service
  _action/feedback                     …ExecuteArticutoolPrimitive_FeedbackMessage topic
  _action/status                       action_msgs/msg/GoalStatusArray             topic
/articutool/joint_trajectory           trajectory_msgs/msg/JointTrajectory         PC → tool
/articutool/joint_states               sensor_msgs/msg/JointState                  tool → PC
/articutool/imu/data                   sensor_msgs/msg/Imu (filtered orientation)  tool → PC
/articutool/health                     diagnostic_msgs/msg/DiagnosticArray         tool → PC
/articutool/battery                    sensor_msgs/msg/BatteryState                tool → PC
/articutool/heartbeat                  std_msgs/msg/Header (frame_id = sender)     tool → PC
/articutool/client_heartbeat           std_msgs/msg/Header (frame_id = sender)     PC → tool
/articutool/take_over                  std_srvs/srv/Trigger (take the lease)       service
/articutool/release                    std_srvs/srv/Trigger (give it back)         service
/articutool/clear_fault                std_srvs/srv/Trigger                        service
=====================================  ==========================================  =========

The tool heartbeat's frame_id is ``<tool_id>/<instance>`` (a random id per tool start).

Deviations from rmw_zenoh (interoperability with ROS 2 nodes on rmw_zenoh is by design, but has
not been tested against a ROS 2 installation):

* No liveliness tokens (``@ros2_lv/...``) are declared, so ``ros2 topic list`` does not see
  the Articutool's endpoints; data keys are unaffected.
* rmw_zenoh attaches (sequence number, source timestamp, GID) to every sample and query. Our
  publishers attach nothing; our service server echoes the request's attachment in its reply
  so an rmw_zenoh client can match the response.
* Type hashes are computed with ``rosbags`` (``hash_rihs01``) over REP 2011 type
  descriptions, for services and actions from hand-built description structs. The standard
  types' hashes equal ROS 2's installed descriptions (``tests/test_link_ros_interop.py``,
  rclpy 9.1.2), and so do our own ``articutool_interfaces`` hashes to those of the package
  ``make`` builds (``tests/test_ros2_interfaces.py``).
  ``type_hash_in_keys=False`` in the config replaces the hash with ``*`` on
  subscribers/queries if a mismatch ever shows up.
* The action's ``get_result`` is a long poll as in ROS 2: the server replies when the goal
  reaches a terminal state; the client re-issues it when the Zenoh query times out.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

from articutool.link import cdr

__all__ = [
    "Endpoint",
    "LinkOpenError",
    "LinkRefusedError",
    "LinkTimeoutError",
    "Names",
    "RateGate",
    "RefusalError",
    "Responder",
    "Transport",
    "key_expr",
]

Responder = Callable[[bytes], None]
"""Sends the reply to one service request; may be called later, from any thread, once."""


class LinkOpenError(RuntimeError):
    """The transport cannot be opened (an endpoint in use, an address not on this host, …)."""


class LinkTimeoutError(TimeoutError):
    """A service call got no reply in time (no server reachable, or it did not answer)."""


class LinkRefusedError(RuntimeError):
    """The server answered with an error instead of a reply (e.g. rate limited)."""


class RefusalError(Exception):
    """Raised by a service handler, before it returns, to answer with an error that names
    the reason (the caller gets LinkRefusedError): for refusals whose reply type has no text
    (SendGoal, CancelGoal) and for rate limits."""


@dataclass(frozen=True)
class Endpoint:
    """A ROS 2 topic or service: fully qualified name and interface type.

    For a topic ``type`` is the message type it carries; for a service it is the service
    type (used in the key) and requests/replies are ``type + '_Request'`` / ``'_Response'``.
    """

    name: str
    type: str
    service: bool = False

    @property
    def request_type(self) -> str:
        """CDR type of a service request (or the topic's message type)."""
        return f"{self.type}_Request" if self.service else self.type

    @property
    def response_type(self) -> str:
        """CDR type of a service reply."""
        if not self.service:
            raise ValueError(f"{self.name} is a topic, not a service")
        return f"{self.type}_Response"


def key_expr(domain_id: int, ep: Endpoint, with_hash: bool = True) -> str:
    """The Zenoh key expression of ``ep`` (see the module docstring)."""
    h = cdr.type_hash(ep.type) if with_hash else "*"
    return f"{domain_id}/{ep.name.strip('/')}/{cdr.dds_type_name(ep.type)}/{h}"


@dataclass(frozen=True)
class Names:
    """All endpoints of the Articutool ``tool_id`` under ``namespace``: ``/<namespace>/<tool_id>/…``
    (default ``/articutool/default/…``), so one client addresses exactly one tool."""

    namespace: str = "/articutool"
    tool_id: str = "default"

    def _n(self, rel: str) -> str:
        base = "/".join(p for p in (self.namespace.strip("/"), self.tool_id) if p)
        return f"/{base}/{rel}"

    @property
    def take_over(self) -> Endpoint:
        """Take the command lease from its holder (audited; a caregiver's stop)."""
        return Endpoint(self._n("take_over"), cdr.TRIGGER, True)

    @property
    def release(self) -> Endpoint:
        """Give the command lease back."""
        return Endpoint(self._n("release"), cdr.TRIGGER, True)

    @property
    def set_orientation_control(self) -> Endpoint:
        """The mode service."""
        return Endpoint(self._n("set_orientation_control"), cdr.SET_ORIENTATION_CONTROL, True)

    @property
    def clear_fault(self) -> Endpoint:
        """The explicit fault clear (reboots motors after a hardware error)."""
        return Endpoint(self._n("clear_fault"), cdr.TRIGGER, True)

    def _action(self, sub: str) -> str:
        return self._n(f"execute_primitive/_action/{sub}")

    @property
    def send_goal(self) -> Endpoint:
        """Action sub-service: send a goal."""
        return Endpoint(self._action("send_goal"), cdr.SEND_GOAL, True)

    @property
    def get_result(self) -> Endpoint:
        """Action sub-service: long-poll a goal's result."""
        return Endpoint(self._action("get_result"), cdr.GET_RESULT, True)

    @property
    def cancel_goal(self) -> Endpoint:
        """Action sub-service: cancel goals."""
        return Endpoint(self._action("cancel_goal"), cdr.CANCEL_GOAL, True)

    @property
    def feedback(self) -> Endpoint:
        """Action feedback topic."""
        return Endpoint(self._action("feedback"), cdr.FEEDBACK_MESSAGE)

    @property
    def status(self) -> Endpoint:
        """Action status topic."""
        return Endpoint(self._action("status"), cdr.GOAL_STATUS_ARRAY)

    @property
    def joint_trajectory(self) -> Endpoint:
        """Wrist trajectories, PC → tool."""
        return Endpoint(self._n("joint_trajectory"), cdr.JOINT_TRAJECTORY)

    @property
    def joint_states(self) -> Endpoint:
        """Joint states, tool → PC."""
        return Endpoint(self._n("joint_states"), cdr.JOINT_STATE)

    @property
    def imu(self) -> Endpoint:
        """Filtered IMU orientation, tool → PC."""
        return Endpoint(self._n("imu/data"), cdr.IMU)

    @property
    def health(self) -> Endpoint:
        """Loop health / fault / mode diagnostics, tool → PC."""
        return Endpoint(self._n("health"), cdr.DIAGNOSTIC_ARRAY)

    @property
    def battery(self) -> Endpoint:
        """Battery (motor input voltage), tool → PC."""
        return Endpoint(self._n("battery"), cdr.BATTERY_STATE)

    @property
    def heartbeat(self) -> Endpoint:
        """Tool heartbeat."""
        return Endpoint(self._n("heartbeat"), cdr.HEADER)

    @property
    def client_heartbeat(self) -> Endpoint:
        """PC heartbeat (the tool's link-loss detector listens to it)."""
        return Endpoint(self._n("client_heartbeat"), cdr.HEADER)


class Handle(ABC):
    """A declared subscriber or service; ``close()`` undeclares it."""

    @abstractmethod
    def close(self) -> None:
        """Undeclare."""


class RateGate:
    """Token bucket: at most ``rate`` messages per second on average, bursts of ``burst``."""

    def __init__(self, rate: float, burst: float | None = None) -> None:
        import threading
        import time

        self.rate = float(rate)
        self.burst = float(burst if burst is not None else max(1.0, rate / 5))
        self._tokens = self.burst
        self._t = time.monotonic()
        self._clock = time.monotonic
        self._lock = threading.Lock()

    def allow(self) -> bool:
        """Take a token if one is left."""
        with self._lock:
            now = self._clock()
            self._tokens = min(self.burst, self._tokens + (now - self._t) * self.rate)
            self._t = now
            if self._tokens >= 1.0:
                self._tokens -= 1.0
                return True
            return False


class Transport(ABC):
    """Publish/subscribe and request/reply of CDR payloads on ROS 2-named endpoints.

    Callbacks run on transport threads: they must return promptly and must not raise (an
    exception is caught and dropped by the transport, but the caller should count it).

    Every message sent carries its sender (``articutool.link.auth``: a signature on a paired
    transport, a bare name otherwise). With ``with_sender=True`` a callback also receives the
    :class:`Sender` (verified before the callback runs, so the receiver can limit each
    sender's rate on its own, and no flood holds back a stop). With ``max_bytes`` a larger
    payload is dropped before it is copied or decoded; ``on_drop(endpoint name, reason)`` (if
    set) is told.
    """

    on_drop: Callable[[str, str], None] | None = None

    def _dropped(self, ep: Endpoint, reason: str) -> None:
        hook = self.on_drop
        if hook is not None:
            hook(ep.name, reason)

    @abstractmethod
    def publish(self, ep: Endpoint, payload: bytes) -> None:
        """Publish on a topic (best effort; never raises for a missing subscriber)."""

    @abstractmethod
    def subscribe(self, ep: Endpoint, callback: Callable[..., None], with_sender: bool = False,
                  max_bytes: int | None = None) -> Handle:
        """Call ``callback(payload[, sender])`` for every sample published on ``ep``."""

    @abstractmethod
    def serve(self, ep: Endpoint, handler: Callable[..., None], with_sender: bool = False,
              max_bytes: int | None = None) -> Handle:
        """Serve a service: ``handler(request, respond[, sender])``; ``respond(reply)`` may be
        deferred. An oversized request is dropped unanswered (the caller times out); a
        handler raising :class:`RefusalError` answers with an error naming the reason
        (LinkRefusedError for the caller)."""

    @abstractmethod
    def call(self, ep: Endpoint, payload: bytes, timeout: float) -> bytes:
        """Call a service and return the reply payload; raise LinkTimeoutError if none arrives."""

    @abstractmethod
    def close(self) -> None:
        """Release the transport (idempotent)."""

    def __enter__(self) -> Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
