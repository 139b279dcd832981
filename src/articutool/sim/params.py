"""Validated parameters of the physics world: solver, servos and food models.

The packaged ``articutool/data/physics.toml`` documents the source of every value (a
physical property, a measurement command, or a numerical choice and its reason).
``PhysicsParams.load(path)`` reads another file of the same shape; every bad value is
refused with its field named (``PhysicsError``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator

from articutool.datafile import (
    NonNegative,
    Positive,
    StrictModel,
    format_validation_error,
    read_document,
)
from articutool.food.definitions import FoodDefinition, default_physics_path, food_definition

__all__ = [
    "CONTACT_PARTNERS",
    "FOOD_KINDS",
    "SPH_BOWL_RADIUS_RANGE_M",
    "SPH_RADIUS_RANGE_M",
    "ContactParams",
    "Food",
    "FoodContacts",
    "Granular",
    "Liquid",
    "PhysicsError",
    "PhysicsParams",
    "Strands",
    "default_physics_path",
]

FOOD_KINDS = ("granular", "liquid", "strands")
# The SPH particle radii (m) the liquid's checks validated (``sim-calibrate --food water``:
# static tilt at both ends against hydrostatics); a radius outside is refused.
SPH_RADIUS_RANGE_M = (0.00075, 0.001)
# The container's SPH liquid: the particle radii whose Exp. 1 scoops kept grams within 6 % of
# each other (studies/bowl_liquid_scoop.py); it hands what the dish holds to the load's size.
SPH_BOWL_RADIUS_RANGE_M = (0.0015, 0.002)
# What a food item can touch, each with its own contact law (``FoodContacts``): another item
# of the food, the utensil, its container (bowl, plate), any other surface (table, floor, the
# user, the wheelchair, the arm's links).
CONTACT_PARTNERS = ("food", "utensil", "container", "surface")


class PhysicsError(ValueError):
    """A physics parameter file is missing, malformed or holds an invalid value."""


class ContactParams(StrictModel):
    """One contact law, as MuJoCo applies it to a pair of geoms: ``condim`` (1 frictionless,
    3 sliding, 4 + torsional, 6 + rolling), ``friction`` (sliding, torsional m, rolling m),
    ``solref`` (time constant s, damping ratio) and ``solimp`` (dmin, dmax, width m, midpoint,
    power)."""

    friction: tuple[NonNegative, NonNegative, NonNegative]
    condim: Literal[1, 3, 4, 6]
    solref: tuple[Positive, Positive]
    solimp: tuple[float, float, float, float, float] = (0.9, 0.95, 0.001, 0.5, 2.0)

    @model_validator(mode="after")
    def _law(self) -> ContactParams:
        dmin, dmax, width, mid, power = self.solimp
        if not all(math.isfinite(v) for v in self.solimp):
            raise ValueError(f"solimp must be finite; got {list(self.solimp)}")
        if not (0 < dmin <= dmax < 1):
            raise ValueError(f"solimp: 0 < dmin <= dmax < 1; got dmin {dmin}, dmax {dmax}")
        if not (width > 0 and 0 < mid < 1 and power >= 1):
            raise ValueError(f"solimp: width > 0 m, 0 < midpoint < 1, power >= 1; got "
                             f"{width}, {mid}, {power}")
        if self.condim > 1 and self.friction[0] <= 0:
            raise ValueError(f"friction: condim {self.condim} needs a sliding friction > 0 "
                             "(use condim 1 for a frictionless contact)")
        return self


class FoodContacts(StrictModel):
    """The contact law of a food against each partner (``CONTACT_PARTNERS``): the world gives
    every such pair exactly these values (``articutool.sim.world_spec``)."""

    food: ContactParams
    utensil: ContactParams
    container: ContactParams
    surface: ContactParams


class WorldParams(StrictModel):
    """Solver options (MuJoCo ``<option>``) and the settling time before a scene."""

    timestep: Annotated[float, Field(gt=0, le=0.01)]
    solver: Literal["CG", "Newton", "PGS"]
    iterations: Annotated[int, Field(ge=1, le=1000)]
    tolerance: Positive
    cone: Literal["elliptic", "pyramidal"]
    sleep: bool
    sleep_tolerance: Positive
    settle_s: NonNegative
    spill_dwell_s: NonNegative
    collision_wall_factor: Annotated[float, Field(ge=1, le=10)]
    # The utensil against containers and surfaces (scraping the bowl): no food in the pair.
    utensil_contact: ContactParams


class ArmServoParams(StrictModel):
    """PD gains with velocity feed-forward of the arm's joint servos."""

    kp: Positive
    kv: Positive
    armature: NonNegative


class WristMotorParams(StrictModel):
    """The XC430 velocity loop: reflected inertia, time constant, gearbox friction."""

    armature: Positive
    time_constant_s: Positive
    integral_time_s: Positive
    frictionloss: NonNegative

    @property
    def kv(self) -> float:
        """Velocity gain (N·m·s/rad) that gives the time constant with the armature."""
        return self.armature / self.time_constant_s

    @property
    def ki(self) -> float:
        """Integral gain (N·m/rad) of the velocity loop."""
        return self.kv / self.integral_time_s


class _FoodBase(StrictModel):
    container: str = Field(min_length=1)
    utensil: str = Field(min_length=1)
    density: Positive
    fill_g: Positive
    contacts: FoodContacts


class Granular(_FoodBase):
    """Rigid irregular pieces (e.g. pecans): halves and broken pieces, compounds of capsules
    drawn by :func:`articutool.sim.pieces.draw_piece`."""

    kind: Literal["granular"]
    half_fraction: Annotated[float, Field(ge=0, le=1)]
    half_width_m: tuple[Positive, Positive]
    half_length_ratio: Annotated[float, Field(ge=1, le=5)]
    piece_screen_m: tuple[Positive, Positive]
    # The cited angle of repose of the food (degrees) that the pile test
    # (``sim-calibrate``) is checked against; also bounds what a utensil can hold.
    angle_of_repose_deg: Annotated[float, Field(gt=0, lt=90)]
    # No-slip solver passes (MuJoCo ``noslip_iterations``): static friction without the
    # soft contacts' creep (a resting heap must not flow); the creep law of ``sim-calibrate``
    # (:func:`articutool.sim.calibrate.creep_mm`) checks what they give.
    noslip_iterations: Annotated[int, Field(ge=0, le=1000)] = 0
    # The passes while the utensil's tip is inside the filled container (within its radius,
    # below its rim; ``None``: ``noslip_iterations`` there too). The world sets them each tool
    # tick (:class:`articutool.sim.world.FeedingWorld`).
    noslip_iterations_digging: Annotated[int, Field(ge=0, le=1000)] | None = None

    # The fields only a filled container reads: a world whose load is placed on the utensil
    # never fills the container, so they do not bear on its trials.
    BOWL_FIELDS: ClassVar[tuple[str, ...]] = ("noslip_iterations_digging",)

    @model_validator(mode="after")
    def _ranges(self) -> Granular:
        for name in ("half_width_m", "piece_screen_m"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name}: [min, max] with min <= max; got [{lo}, {hi}]")
        return self

    @property
    def piece_mass(self) -> float:
        """kg: the mean piece mass (4000 pieces drawn with a fixed seed)."""
        from articutool.sim.pieces import capsule_mass, draw_piece

        rng = np.random.default_rng(0)
        return float(np.mean([capsule_mass(draw_piece(self, rng), self.density)
                              for _ in range(4000)]))


class Liquid(_FoodBase):
    """A liquid (e.g. water). By default (``load_model = "sph"``) it is an SPH liquid
    (SPlisHSPlasH) coupled to MuJoCo: a load placed on the utensil in the utensil's frame
    (:mod:`articutool.sim.liquid_load`), a container's fill in the container with the dish an
    animated boundary (:mod:`articutool.sim.bowl_liquid`). With ``load_model = "spheres"``
    both are frictionless MuJoCo spheres standing in for it."""

    # The fields only the container's SPH fill reads: a world whose load is placed on the
    # utensil never fills the container, so they do not bear on its trials.
    BOWL_FIELDS: ClassVar[tuple[str, ...]] = (
        "sph_bowl_particle_radius", "sph_bowl_wake_m", "sph_bowl_handover_m",
        "sph_bowl_settle_s")

    kind: Literal["liquid"]
    particle_radius: Positive  # a container fill
    load_particle_radius: Positive  # a load placed on the utensil as spheres
    # A placed load's radii spread uniformly by ± this fraction (a disordered packing).
    load_radius_spread: Annotated[float, Field(ge=0, lt=0.5)] = 0.0
    packing_fraction: Annotated[float, Field(gt=0, le=0.74)]
    # What a placed load is: the SPH liquid, or the spheres (kept for comparison).
    load_model: Literal["sph", "spheres"] = "sph"
    # The SPH particle radius (m), within the range the static-tilt checks validated.
    sph_particle_radius: Positive = 0.001
    # Kinematic viscosity (m²/s) of the SPH liquid.
    viscosity: NonNegative = 1.0e-6
    # The container's SPH liquid (a fill, with ``load_model = "sph"``): its particle radius
    # (m), and the dish's heights above the liquid's surface (m) at which the liquid starts
    # being stepped (``sph_bowl_wake_m``) and, after a dip, is handed to the load
    # (``sph_bowl_handover_m``); the fill settles ``sph_bowl_settle_s`` first.
    sph_bowl_particle_radius: Positive = 0.002
    sph_bowl_wake_m: Positive = 0.03
    sph_bowl_handover_m: Positive = 0.015
    sph_bowl_settle_s: Positive = 0.5

    @model_validator(mode="after")
    def _sph_radius(self) -> Liquid:
        lo, hi = SPH_RADIUS_RANGE_M
        if not lo - 1e-12 <= self.sph_particle_radius <= hi + 1e-12:
            raise ValueError(f"sph_particle_radius must be in [{lo * 1e3:g}, {hi * 1e3:g}] mm "
                             f"(the sizes the static-tilt checks validated); got "
                             f"{self.sph_particle_radius * 1e3:g} mm")
        lo, hi = SPH_BOWL_RADIUS_RANGE_M
        if not lo - 1e-12 <= self.sph_bowl_particle_radius <= hi + 1e-12:
            raise ValueError(f"sph_bowl_particle_radius must be in [{lo * 1e3:g}, "
                             f"{hi * 1e3:g}] mm (the sizes whose scoops were compared); got "
                             f"{self.sph_bowl_particle_radius * 1e3:g} mm")
        if not self.sph_bowl_handover_m < self.sph_bowl_wake_m:
            raise ValueError("sph_bowl_handover_m must be below sph_bowl_wake_m")
        return self

    @property
    def sph_load(self) -> bool:
        """A placed load is the SPH liquid."""
        return self.load_model == "sph"

    def sph_particle_mass(self) -> float:
        """kg per SPH particle: ρ0 · (2r)³ (SPlisHSPlasH's own particle mass)."""
        return self.density * (2.0 * self.sph_particle_radius) ** 3

    @property
    def load_item_mass(self) -> float:
        """kg of one item of a placed load: an SPH particle, or a load sphere."""
        return (self.sph_particle_mass() if self.sph_load
                else self.particle_mass(self.load_particle_radius))

    def particle_mass(self, radius: float) -> float:
        """kg per particle of ``radius``: density × sphere volume / packing fraction."""
        return self.density * 4.0 / 3.0 * math.pi * radius**3 / self.packing_fraction

    @property
    def piece_mass(self) -> float:
        """kg per particle of a container fill."""
        return self.particle_mass(self.particle_radius)


class Strands(_FoodBase):
    """Elastic strands (e.g. noodles): chains of capsule bodies with ball-joint bending springs,
    heaped in the container (:func:`articutool.sim.food_strands.strand_chain`)."""

    kind: Literal["strands"]
    strand_radius: Positive
    strand_length: Positive
    segments: Annotated[int, Field(ge=2, le=200)]
    young: Positive
    bend_damping_s: Positive
    pile_radius: Positive
    noslip_iterations: Annotated[int, Field(ge=0, le=1000)]
    # Starch tack: the measured stickiness (N/m², pull-off force per area) over a contact band
    # ``tack_width`` wide, acting across ``adhesion_gap`` (MuJoCo's contact adhesion acts only
    # across a gap). 0 = friction only.
    stickiness_pa: NonNegative = 0.0
    tack_width: Positive = 0.001
    adhesion_gap: Annotated[float, Field(ge=0, le=0.002)] = 0.0
    # The strand–strand contacts' tack over a right-angle crossing's: the mean, over a settled
    # nest's strand–strand contact points, of the film's law at each one's angle
    # (:func:`articutool.sim.strand_laws.contact_tack`) over its value at 90°. MuJoCo's adhesion
    # is one value a geom, not a value an angle. 1 = the right angle's.
    crossing_factor: Annotated[float, Field(ge=1.0, le=10.0)] = 1.0

    @model_validator(mode="after")
    def _adhesion_needs_a_gap(self) -> Strands:
        if self.stickiness_pa and not self.adhesion_gap:
            raise ValueError("adhesion_gap must be > 0 when stickiness_pa is set "
                             "(MuJoCo's contact adhesion acts only across the gap)")
        return self

    @property
    def piece_mass(self) -> float:
        """kg per strand."""
        return self.density * math.pi * self.strand_radius**2 * self.strand_length

    @property
    def segment_length(self) -> float:
        """m: one capsule's length, ds = L / segments."""
        return self.strand_length / self.segments

    @property
    def bend_stiffness(self) -> float:
        """N·m/rad of each joint: the rod's E·I over the segment length (I = π r⁴ / 4)."""
        inertia = math.pi * self.strand_radius**4 / 4.0
        return self.young * inertia / self.segment_length

    @property
    def tack_per_length(self) -> float:
        """N/m: the pull-off force per metre of a strand lying on a surface, stickiness ×
        contact band width."""
        return self.stickiness_pa * self.tack_width

    @property
    def tack_per_contact(self) -> float:
        """N: MuJoCo's adhesion of one contact point of a strand lying on the fork. A segment
        lying along a surface touches it at two points (its capsule's two ends), so each
        carries the tack of half a segment: stickiness × width × ds / 2."""
        return self.tack_per_length * self.segment_length / 2.0

    @property
    def film_thickness(self) -> float:
        """m: the gap h below which the starch film wets, as the band implies it. A cylinder of
        radius r on a plane stands x²/(2r) off it at x from its line of contact, so a band
        ``tack_width`` w wide is where that gap is below h = w²/(8r)."""
        return self.tack_width**2 / (8.0 * self.strand_radius)

    @property
    def tack_per_crossing(self) -> float:
        """N: the pull-off force of two strands crossed at right angles. Near the crossing two
        cylinders of radius r stand (x² + y²)/(2r) apart (each curves in one direction), so
        the film (:attr:`film_thickness` h) wets a disk of radius √(2rh), area 2π·r·h
        (= π·w²/4, a disk as wide as the band): stickiness × that area, over one contact point
        (MuJoCo gives a crossing one). At an angle θ the wetted ellipse is 2π·r·h / sin θ:
        the right angle is the least (:func:`articutool.sim.strand_laws.crossing_tack`)."""
        return self.stickiness_pa * 2.0 * math.pi * self.strand_radius * self.film_thickness

    @property
    def tack_per_strand_contact(self) -> float:
        """N: the adhesion of one strand–strand contact point in the model: the right-angle
        crossing's (:attr:`tack_per_crossing`) × :attr:`crossing_factor`, the mean of the film's
        law over a settled nest's contact angles."""
        return self.tack_per_crossing * self.crossing_factor

    @property
    def tack_per_length_parallel(self) -> float:
        """N/m: the pull-off force per metre of two parallel strands lying along each other.
        Both curve across the line of contact, so they stand x²/r apart and the film wets a
        band 2·√(r·h) = w/√2 wide: stickiness × w/√2."""
        return self.stickiness_pa * 2.0 * math.sqrt(self.strand_radius * self.film_thickness)


Food = Annotated[Granular | Liquid | Strands, Field(discriminator="kind")]


class PhysicsParams(StrictModel):
    """The whole parameter file."""

    version: Annotated[int, Field(ge=2, le=2)] = 2
    world: WorldParams
    arm_servo: ArmServoParams
    wrist_motor: WristMotorParams
    foods: dict[str, Food] = Field(min_length=1)

    @model_validator(mode="after")
    def _names(self) -> PhysicsParams:
        for name in self.foods:
            if not name.isidentifier():
                raise ValueError(f"food name {name!r} must be an identifier")
        return self

    def food(self, name: str) -> Granular | Liquid | Strands:
        """The named food; unknown names list the known ones."""
        if name not in self.foods:
            raise PhysicsError(f"food: unknown food {name!r}; allowed: {sorted(self.foods)}")
        return self.foods[name]

    def definition(self, name: str) -> FoodDefinition:
        """The named food as a planner reads it (:mod:`articutool.food.definitions`)."""
        return food_definition(name, self.food(name).model_dump())

    @classmethod
    def from_dict(cls, data: Any, source: str = "<dict>") -> PhysicsParams:
        """Validate a mapping; errors name the field (e.g. ``foods.pecans.density``)."""
        try:
            return cls.model_validate(data)
        except ValidationError as err:
            raise PhysicsError(
                format_validation_error(err, f"invalid physics parameters {source}:")
            ) from None

    @classmethod
    def load(cls, path: str | Path | None = None) -> PhysicsParams:
        """Load and validate a parameter file; ``None`` loads the packaged default."""
        p = Path(path) if path is not None else default_physics_path()
        return cls.from_dict(read_document(p, "physics parameters", PhysicsError), str(p))
