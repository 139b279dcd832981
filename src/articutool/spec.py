"""The hardware spec: one validated TOML file holds every limit, rate and geometry number.

The packaged default is ``articutool/data/hardware.toml`` (values from
``docs/hardware.md``). ``load_spec(path)`` reads another file of the same
shape; unknown keys, NaN/inf, negative speeds and inverted limits fail with a message naming
the field.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import AfterValidator, Field, ValidationError, model_validator

from articutool.datafile import (
    Finite,
    NonNegative,
    Positive,
    StrictModel,
    Unit,
    Vec3,
    check_finite,
    format_validation_error,
    read_document,
)
from articutool.dynamixel_units import bus_watchdog_units

if TYPE_CHECKING:
    import numpy as np

__all__ = [
    "ArmJointSpec",
    "ArmSpec",
    "CollisionSpec",
    "ControllerSpec",
    "FilterSpec",
    "PlanningSpec",
    "PrimitivesSpec",
    "Spec",
    "SpecError",
    "UtensilSpec",
    "WristSpec",
    "default_spec_path",
    "load_spec",
]


class SpecError(ValueError):
    """A hardware spec file is missing, malformed or holds an invalid value."""


def _check_interval(lo: float, hi: float, name: str) -> None:
    if not lo < hi:
        raise ValueError(f"{name}: lower ({lo}) must be below upper ({hi})")


class ArmJointSpec(StrictModel):
    """One Jaco joint as in Kinova's URDF: origin in the parent frame, rotation about local z."""

    name: str
    xyz: Vec3
    rpy: Vec3
    lower: Finite
    upper: Finite
    continuous: bool
    max_velocity: Positive
    max_acceleration: Positive
    effort: Positive

    @model_validator(mode="after")
    def _limits(self) -> ArmJointSpec:
        _check_interval(self.lower, self.upper, f"joint {self.name} limits")
        return self


class PoseSpec(StrictModel):
    """A pose in the arm base frame; quaternion order (w, x, y, z)."""

    position: Vec3
    orientation_wxyz: tuple[Finite, Finite, Finite, Finite]

    @model_validator(mode="after")
    def _unit(self) -> PoseSpec:
        n = math.sqrt(sum(c * c for c in self.orientation_wxyz))
        if abs(n - 1.0) > 1e-3:
            raise ValueError(f"orientation_wxyz must be a unit quaternion (norm {n:.4f})")
        return self


class ArmSpec(StrictModel):
    """Kinova Jaco 2 (j2n6s200): joint table, end-effector frame, named configurations."""

    model: str
    base_frame: str
    ee_frame: str
    ee_xyz: Vec3
    ee_rpy: Vec3
    joints: list[ArmJointSpec] = Field(min_length=6, max_length=6)
    configurations: dict[str, tuple[Finite, Finite, Finite, Finite, Finite, Finite]]
    poses: dict[str, PoseSpec] = Field(default_factory=dict)
    # kg, links 1..6; used by the physics world only (articutool.sim)
    link_masses: tuple[Positive, Positive, Positive, Positive, Positive, Positive]

    @property
    def joint_names(self) -> list[str]:
        """Arm joint names in chain order."""
        return [j.name for j in self.joints]

    @property
    def lower(self) -> np.ndarray:
        """Lower position limits (rad), shape (6,)."""
        import numpy as np

        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        """Upper position limits (rad), shape (6,)."""
        import numpy as np

        return np.array([j.upper for j in self.joints])

    @property
    def max_velocity(self) -> np.ndarray:
        """Joint speed limits (rad/s), shape (6,)."""
        import numpy as np

        return np.array([j.max_velocity for j in self.joints])

    @property
    def max_acceleration(self) -> np.ndarray:
        """Joint acceleration limits (rad/s²), shape (6,)."""
        import numpy as np

        return np.array([j.max_acceleration for j in self.joints])

    def configuration(self, name: str) -> np.ndarray:
        """A named joint configuration, e.g. ``"AbovePlate"``."""
        import numpy as np

        if name not in self.configurations:
            raise KeyError(
                f"unknown configuration {name!r}; known: {sorted(self.configurations)}"
            )
        return np.array(self.configurations[name])


class WristSpec(StrictModel):
    """The Articutool's 2-DOF pitch/roll wrist (joint order everywhere: [pitch, roll])."""

    joint_names: tuple[str, str]
    mount_xyz: Vec3
    mount_rpy: Vec3
    pitch_z: NonNegative
    roll_dz: NonNegative
    utensil_mount_dz: NonNegative
    mass_kg: Positive
    distal_mass_kg: Positive  # of mass_kg, what turns with the roll joint
    pitch_limits: tuple[Finite, Finite]
    roll_limits: tuple[Finite, Finite]
    roll_turn_budget: Positive
    max_velocity: tuple[Positive, Positive]
    motor_max_velocity: Positive
    loop_rate_hz: Positive

    @model_validator(mode="after")
    def _consistent(self) -> WristSpec:
        if self.joint_names[0] == self.joint_names[1]:
            raise ValueError("wrist.joint_names must be two different names [pitch, roll]; "
                             f"got {list(self.joint_names)}")
        _check_interval(*self.pitch_limits, "wrist.pitch_limits")
        _check_interval(*self.roll_limits, "wrist.roll_limits")
        for name, v in zip(self.joint_names, self.max_velocity, strict=True):
            if v > self.motor_max_velocity:
                raise ValueError(
                    f"wrist.max_velocity for {name} ({v} rad/s) exceeds "
                    f"wrist.motor_max_velocity ({self.motor_max_velocity} rad/s)"
                )
        return self

    @property
    def limits(self) -> np.ndarray:
        """Leveling/verification limits, (2, 2): [[pitch_lo, pitch_hi], [roll_lo, roll_hi]]."""
        import numpy as np

        return np.array([self.pitch_limits, self.roll_limits])

    @property
    def velocity_limits(self) -> np.ndarray:
        """Commandable joint speed (rad/s), shape (2,)."""
        import numpy as np

        return np.array(self.max_velocity)

    @property
    def period(self) -> float:
        """Control loop period (s)."""
        return 1.0 / self.loop_rate_hz


class UtensilShape(StrictModel):
    """Physics shape of a utensil (``articutool.sim``), in the roll-link frame.

    ``kind = "spoon"``: a dish whose far end is the tip, ``bowl = [length, width, depth]``
    (inner), floor at the tip's x, opening towards +x (the up vector). ``kind = "fork"``:
    ``tines`` capsules of ``tine_radius``, ``tine_pitch`` apart, ``tine_length`` long, ending at
    the tip. Both have a handle strip of ``thickness`` from the utensil mount.
    """

    kind: Literal["spoon", "fork"]
    mass_kg: Positive
    thickness: Positive
    bowl: tuple[Positive, Positive, Positive] | None = None
    tines: Annotated[int, Field(ge=1, le=8)] | None = None
    tine_length: Positive | None = None
    tine_radius: Positive | None = None
    tine_pitch: Positive | None = None

    @model_validator(mode="after")
    def _complete(self) -> UtensilShape:
        need = ("bowl",) if self.kind == "spoon" else (
            "tines", "tine_length", "tine_radius", "tine_pitch")
        missing = [n for n in need if getattr(self, n) is None]
        if missing:
            raise ValueError(f"a {self.kind} needs {', '.join(missing)}")
        return self


class UtensilSpec(StrictModel):
    """Utensil tip offset from the utensil mount, in the roll-link frame (x up at zero, z out)."""

    tip_x: Finite
    tip_z: Positive
    physics: UtensilShape


class CollisionSpec(StrictModel):
    """Collision primitives (approx.) for ``articutool.arm``: capsule radii and skipped pairs.

    ``link_radii[i]`` is the capsule radius of Jaco link i+1, which runs from joint i+1 to the
    next joint (link 6, the hand, runs to the end-effector frame). ``excluded_pairs`` names
    geometry pairs that touch by construction beyond the adjacent ones, e.g. the compact wrist.
    """

    base_radius: Positive
    link_radii: tuple[Positive, Positive, Positive, Positive, Positive, Positive]
    wrist_body_radius: Positive
    wrist_distal_radius: Positive
    utensil_radius: Positive
    excluded_pairs: list[tuple[str, str]] = Field(default_factory=list)


class ControllerSpec(StrictModel):
    """Leveling controller gains (thesis Alg. 1; docs/hardware.md §5)."""

    kp: NonNegative
    ki: NonNegative
    kd: NonNegative
    integral_clamp: NonNegative
    deadband: NonNegative
    pinv_rcond: Annotated[float, AfterValidator(check_finite), Field(gt=0, lt=1)]
    damping_threshold: Annotated[float, AfterValidator(check_finite), Field(gt=0, le=1)]
    damping_power: Positive
    limit_gain: Positive  # 1/s: speed towards a joint limit ≤ limit_gain × distance left
    stall_deg: Positive  # leveling error above which a near-zero command is a stall
    stall_s: Positive  # ... for this long


class PrimitivesSpec(StrictModel):
    """Closed-loop moves inside the primitives (thesis §4.4; docs/hardware.md §6)."""

    position_gain: Positive
    position_tolerance: Positive
    timeout_factor: Annotated[float, AfterValidator(check_finite), Field(ge=1)]
    timeout_margin_s: NonNegative
    max_hold_s: Positive  # longest wait inside a primitive (TILT hold, NOODLE_SHED delay)
    max_vibrate_s: Positive  # longest vibration (VIBRATE_ROLL, NOODLE_SHED)
    max_duration_s: Positive  # longest nominal duration of a whole primitive
    settle_toss_overshoot_rad: Positive  # how far SETTLE_TOSS's flick passes the start pitch

    @model_validator(mode="after")
    def _bounded(self) -> PrimitivesSpec:
        for key in ("max_hold_s", "max_vibrate_s"):
            if getattr(self, key) > self.max_duration_s:
                raise ValueError(f"primitives.{key} ({getattr(self, key)} s) exceeds "
                                 f"primitives.max_duration_s ({self.max_duration_s} s)")
        return self


class FilterSpec(StrictModel):
    """Complementary filter parameters (Valenti et al. 2015; docs/hardware.md §4)."""

    gain_acc: Unit
    bias_alpha: Unit
    adaptive_gain: bool
    bias_estimation: bool


class MotorSpec(StrictModel):
    """Dynamixel bus and unit conversions."""

    model: str
    port: str
    baudrate: Annotated[int, Field(gt=0)]
    protocol: float
    pitch_id: Annotated[int, Field(ge=0, le=252)]
    roll_id: Annotated[int, Field(ge=0, le=252)]
    ticks_per_rev: Annotated[int, Field(gt=0)]
    velocity_unit_rpm: Positive
    voltage_unit_v: Positive
    supply_v: Positive
    stall_torque_nm: Positive  # N·m at supply_v (the physics world's torque limit)
    # Encoder ticks at which each joint reads 0 rad ([pitch, roll]); calibrate per build.
    zero_ticks: tuple[
        Annotated[int, Field(ge=0, le=4095)], Annotated[int, Field(ge=0, le=4095)]
    ] = (2048, 2048)
    reboot_below_c: Finite  # °C: an overheated motor is rebooted only below this
    # s: the motors stop themselves after this long without a packet (Bus Watchdog, 98)
    bus_watchdog_s: Positive

    @model_validator(mode="after")
    def _watchdog_fits(self) -> MotorSpec:
        try:
            bus_watchdog_units(self.bus_watchdog_s)
        except ValueError as err:
            raise ValueError(f"motors.bus_watchdog_s: {err} (X-series Bus Watchdog "
                             "register)") from None
        return self


class ImuSpec(StrictModel):
    """OpenLog Artemis IMU stream."""

    port: str
    baudrate: Annotated[int, Field(gt=0)]
    rate_hz: Positive
    gravity: Positive
    gyro_noise_dps_rthz: NonNegative
    accel_noise_ug_rthz: NonNegative


class FTSpec(StrictModel):
    """Resense HEX21 force/torque stream."""

    port: str
    baudrate: Annotated[int, Field(gt=0)]
    rate_hz: Positive
    tare_samples: Annotated[int, Field(gt=0)]
    force_noise_n: NonNegative  # 1 σ per sample (simulated sensor)
    torque_noise_nm: NonNegative


class PlanningSpec(StrictModel):
    """Transport planning tolerances (thesis §5.2, Exp. 2a; docs/hardware.md §7)."""

    strict_tolerance_deg: Annotated[float, AfterValidator(check_finite), Field(gt=0, lt=90)]
    loose_roll_deg: Annotated[float, AfterValidator(check_finite), Field(gt=0, le=90)]
    loose_pitch_deg: Annotated[float, AfterValidator(check_finite), Field(gt=0, le=180)]


class PowerSpec(StrictModel):
    """Measured power budget (thesis §3.1)."""

    idle_w: Positive
    leveling_w: Positive
    peak_w: Positive
    battery_wh: Positive


class Spec(StrictModel):
    """The whole hardware spec."""

    version: Annotated[int, Field(ge=1, le=1)]
    arm: ArmSpec
    wrist: WristSpec
    utensils: dict[str, UtensilSpec] = Field(min_length=1)
    collision: CollisionSpec
    controller: ControllerSpec
    filter: FilterSpec
    primitives: PrimitivesSpec
    motors: MotorSpec
    imu: ImuSpec
    ft: FTSpec
    power: PowerSpec
    planning: PlanningSpec

    @model_validator(mode="after")
    def _distinct_joints(self) -> Spec:
        names = self.arm.joint_names
        if len(set(names)) != len(names):
            raise ValueError(f"arm.joints names must be distinct; got {names}")
        shared = sorted(set(names) & set(self.wrist.joint_names))
        if shared:
            raise ValueError(f"wrist.joint_names must differ from the arm's joint names; "
                             f"{shared} is in both")
        if self.motors.bus_watchdog_s < 2.0 * self.wrist.period:
            raise ValueError(f"motors.bus_watchdog_s ({self.motors.bus_watchdog_s} s) must be at "
                             f"least two loop periods ({2.0 * self.wrist.period:g} s): one late "
                             "tick must not stop the motors")
        return self

    def utensil(self, name: str) -> UtensilSpec:
        """The named utensil; unknown names list the known ones."""
        if name not in self.utensils:
            raise SpecError(f"unknown utensil {name!r}; known: {sorted(self.utensils)}")
        return self.utensils[name]


def default_spec_path() -> Path:
    """Path of the spec shipped with the package."""
    return Path(str(resources.files("articutool") / "data" / "hardware.toml"))


def parse_spec(data: dict, source: str = "<dict>") -> Spec:
    """Validate a spec given as a mapping (e.g. parsed TOML)."""
    try:
        return Spec.model_validate(data)
    except ValidationError as err:
        raise SpecError(format_validation_error(err, f"invalid hardware spec {source}:")) from None


def load_spec(path: str | Path | None = None) -> Spec:
    """Load and validate a hardware spec; ``None`` loads the packaged default."""
    p = Path(path) if path is not None else default_spec_path()
    data = read_document(p, "hardware spec", SpecError)
    return parse_spec(data, str(p))
