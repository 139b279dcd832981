"""A liquid simulated by SPlisHSPlasH (``pysplishsplash`` 2.19): a thin, typed wrapper.

**Contract.** :class:`SphLiquid` builds one SPlisHSPlasH scene from closed triangle meshes
(:class:`Boundary`, given as arrays) and liquid given as boxes (:class:`FluidBlock`) or as
particle positions (:class:`FluidParticles`), all one fluid (water's material), with the
solver settings of :class:`SphSettings` (DFSPH pressure solver, Akinci et al. 2012 boundary
particles sampled regularly on the meshes, the standard SPH viscosity with water's kinematic
viscosity, CFL time steps capped at ``max_dt``). Units are SI; the frame is whatever frame the
caller gives the meshes, the blocks and the gravity in (the library has no preferred "up":
gravity is a vector).

- :meth:`SphLiquid.step_to` advances to a simulated time with the library's own adaptive
  (CFL) steps; it stops at the first step that reaches the time, so ``time`` may overshoot it
  by less than one step (at most ``max_dt``).
- :meth:`SphLiquid.set_gravity` changes the (apparent) gravity between steps: a liquid carried
  by a translating utensil, simulated in the utensil's frame, sees ``g − a(t)``.
- ``extra_acceleration`` (a callable of positions and velocities returning (N, 3) m/s²) adds a
  body acceleration that is not uniform, such as the rotation terms of a turning frame
  (``−ω̇×x − 2ω×v − ω×(ω×x)``, :func:`rotating_frame_acceleration`). The 2.19 bindings expose
  no hook inside a time step, so it is applied after each library step as a velocity change
  ``v += Δt·a(x, v)`` (first-order operator splitting; the next step's divergence and pressure
  solves see it). It is meant for terms small against gravity.
- :meth:`SphLiquid.set_boundary_pose` moves an *animated* boundary (declared
  ``animated=True``) or a *held* one (``held=True``): it sets the rigid body's position,
  rotation, velocity and angular velocity and moves its boundary particles at once (the
  velocities enter the pressure solve).
- A *held* boundary is one whose force the library reads: a dynamic body of the library's
  rigid-body solver (PositionBasedDynamics) that the wrapper puts back at the pose and
  velocities last set before every step. The library adds the liquid's force on it to its
  velocity after the step (``v += F·h/m``, with the rigid-body solver's own gravity
  ``_PBD_GRAVITY``), so ``F = m·((v₁ − v₀)/h − g_PBD)``; :meth:`SphLiquid.held_force` is its
  mean over the steps since the last read. A mean over many steps is exact; a single step is
  off where the CFL step changes size, because the library applies the divergence solve's
  force, computed with the last step's size, over this step's (measured on a block dragged
  through water: up to 15 % of the liquid's weight in a step, 2.6 % over 5 steps, 0.07 % over
  0.2 s). (The library's ``getForceAndTorque`` is bound with
  output arguments pybind copies, and its sum is cleared inside the step: it reads 0.) Any
  held body puts every boundary under that solver; the others stay where they are.
- :meth:`SphLiquid.positions`, :meth:`SphLiquid.velocities` and
  :meth:`SphLiquid.particle_ids` are copies of the active particles' state;
  :meth:`SphLiquid.remove_particles` takes particles out of the simulation (for a particle
  that left the utensil and is handed to the accounting): they are moved past the active
  range, parked far from everything and no longer simulated. Ids are stable (the library's
  z-sort, which would permute them, is off).
- The liquid's force on what holds it, where one body holds it all, is the momentum balance
  of the particles, :func:`momentum_balance_force` and :func:`momentum_balance_torque` —
  exact because SPH's pressure forces are pairwise antisymmetric; on one body among others
  (a dish in a bowl of liquid) it is a held boundary's :meth:`SphLiquid.held_force`.

**Quirks of the 2.19 bindings handled here.** The library is loaded only through
:func:`articutool.sim.sph_library.load_splishsplash` (it segfaults on import otherwise on
machines with libglvnd). Boundary models exist only after ``SimulatorBase.deferredInit``,
which Python reaches only through ``runSimulation()``: the wrapper runs it with a stop time
of 1 ns, which takes exactly one first time step (of at most ``max_dt``) under the initial
gravity, then steps with ``timeStepNoGUI()``. The scene file uses the per-solver namespaces
of the 2025 format (``"DFSPH": {...}``, ``"Standard viscosity": {...}``). A particle's mass
is ``ρ0·(2r)³`` (the library's, read back). The library keeps its scene in process-wide
singletons: one :class:`SphLiquid` is open per process at a time (another raises
:class:`RuntimeError` until the first is closed).

**Threads.** SPlisHSPlasH parallelises with OpenMP. The wrapper sets ``OMP_NUM_THREADS`` to
``settings.threads`` (default 1) before the library's first load unless the variable is set,
and sets the OpenMP runtime's thread count with ``omp_set_num_threads`` whenever a liquid is
built, so the count is ``settings.threads`` whatever the environment. On a loaded 2-core
machine one thread was faster than two (``liquid-notes.md``).

**Reproducible.** A scene gives the same bits in every process on one machine: its boundary
particles are the library's regular triangle sampling of each mesh. The library's default,
Poisson-disk sampling, draws a different sample in every run (measured: two fresh processes of
one 648-particle box differed by 0.7 µm after the first 2 ms step and by 3–4 mm after 60
steps), so no two runs of a water trial agreed.

**Files.** The scene JSON and the meshes (OBJ) are written to a temporary directory the
liquid owns and removes on :meth:`SphLiquid.close` (also a context manager); nothing is read
from or written to the user's directories, and the library's cache is off. The library logs
to the process's standard output (file descriptor 1, no binding to silence it): while it
builds, steps (:meth:`SphLiquid.step_to`) and closes, descriptor 1 is sent to a log file in
that directory.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from articutool.sim.sph_library import library_version, load_splishsplash

__all__ = [
    "Boundary",
    "FluidBlock",
    "FluidParticles",
    "SphLiquid",
    "SphSettings",
    "box_mesh",
    "close_this_threads_liquid",
    "momentum_balance_force",
    "momentum_balance_torque",
    "rotating_frame_acceleration",
]

ExtraAcceleration = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]

_DFSPH = 4  # SPlisHSPlasH's simulation method ids (scene file doc)
_AKINCI2012 = 0  # boundary handling: boundary particles
# a viscosity method's scene id and its parameters' namespace in the scene file
_VISCOSITY_METHODS = {"standard": (1, "Standard viscosity"),
                      "weiler2018": (6, "Weiler et al. 2018")}
_CFL = 1
_REGULAR_SAMPLING = 1  # a boundary mesh's particles: the library's regular triangle sampling
_FIRST_STOP = 1e-9  # s: runSimulation's stop time; it takes exactly one step
_PARK = 1.0e3  # m: where removed particles are parked, far from any scene
# A held body's density (kg/m³): its mass only scales the velocity change its force is read
# from; light, so the library's single-precision positions leave a fine force resolution.
_HELD_DENSITY = 10.0
# PositionBasedDynamics' gravity, which the library's rigid-body solver applies to a dynamic
# body (its scene loader's default; the liquid's gravity does not reach it).
_PBD_GRAVITY = np.array([0.0, -9.81, 0.0])


def _vec3(v: ArrayLike, name: str) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers; got {v!r}")
    return a


@dataclass(frozen=True)
class Boundary:
    """A closed triangle mesh the liquid cannot cross (m; faces index the vertices).

    ``animated``: the body is moved by :meth:`SphLiquid.set_boundary_pose`; its mesh
    coordinates are its own frame (the pose maps them into the scene's frame). ``held``: the
    same, and the liquid's force on it is read (:meth:`SphLiquid.held_force`)."""

    name: str
    vertices: NDArray[np.float64] = field(repr=False)
    faces: NDArray[np.int64] = field(repr=False)
    animated: bool = False
    held: bool = False

    def __post_init__(self) -> None:
        if self.animated and self.held:
            raise ValueError(f"boundary {self.name!r}: animated or held, not both")
        v = np.asarray(self.vertices, dtype=float)
        f = np.asarray(self.faces)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or not np.all(np.isfinite(v)):
            raise ValueError(f"boundary {self.name!r}: vertices must be (N >= 4, 3) finite")
        if (f.ndim != 2 or f.shape[1] != 3 or len(f) < 4 or not np.issubdtype(f.dtype, np.integer)
                or f.min() < 0 or f.max() >= len(v)):
            raise ValueError(f"boundary {self.name!r}: faces must be (M >= 4, 3) indices into "
                             f"the {len(v)} vertices")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f.astype(np.int64))

    def write_obj(self, path: Path) -> None:
        """The mesh as a Wavefront OBJ file (1-based faces)."""
        lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in self.vertices]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in self.faces]
        path.write_text("\n".join(lines) + "\n")


def box_mesh(lower: ArrayLike, upper: ArrayLike) -> tuple[NDArray[np.float64],
                                                          NDArray[np.int64]]:
    """A closed axis-aligned box from ``lower`` to ``upper`` (m): 8 vertices, 12 triangles,
    normals outward."""
    lo, hi = _vec3(lower, "lower"), _vec3(upper, "upper")
    if not np.all(hi > lo):
        raise ValueError(f"a box needs upper > lower on every axis; got {lo}, {hi}")
    v = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1],
                   hi[2] if i & 4 else lo[2]] for i in range(8)])
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]],
                 dtype=np.int64)
    return v, f


@dataclass(frozen=True)
class FluidBlock:
    """A box of liquid from ``lower`` to ``upper`` (m), at rest: tiled by the particles'
    cubes of side ``2r`` (centres at ``lower + r, lower + 3r, …``), so ``round(extent / 2r)``
    particles per axis (at least 2) and a mass of ``ρ0 × their cubes' volume``. (The library's
    dense block puts ``round(L / 2r) − 1`` particles from ``start + 2r``; the wrapper passes it
    the box grown by ``r`` on every side.)"""

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]

    def __post_init__(self) -> None:
        lo, hi = _vec3(self.lower, "lower"), _vec3(self.upper, "upper")
        if not np.all(hi > lo):
            raise ValueError(f"a fluid block needs upper > lower on every axis; got "
                             f"{self.lower}, {self.upper}")


@dataclass(frozen=True)
class FluidParticles:
    """Liquid particles at given positions (m, (N, 3), at rest), e.g. a load placed in a
    dish: each stands for a cube of side ``2r`` of liquid (keep the centres about ``2r`` apart
    and ``2r`` off the boundaries). Passed to the library as a Partio ASCII (PDA) file."""

    positions: NDArray[np.float64] = field(repr=False)

    def __post_init__(self) -> None:
        x = np.asarray(self.positions, dtype=float)
        if x.ndim != 2 or x.shape[1] != 3 or len(x) < 1 or not np.all(np.isfinite(x)):
            raise ValueError(f"fluid particles must be (N >= 1, 3) finite positions; got "
                             f"shape {x.shape}")
        object.__setattr__(self, "positions", x)

    def write_pda(self, path: Path) -> None:
        """The positions as a Partio ASCII particle file."""
        head = ("ATTRIBUTES\nposition\nTYPES\nV\n"
                f"NUMBER_OF_PARTICLES: {len(self.positions)}\nBEGIN DATA\n")
        body = "\n".join(f"{x:.9g} {y:.9g} {z:.9g}" for x, y, z in self.positions)
        path.write_text(head + body + "\n")


@dataclass(frozen=True)
class SphSettings:
    """Solver settings (SI). ``max_density_error_pct``: DFSPH's tolerated mean density error
    (percent); ``max_divergence_error_pct``: its divergence solver's. ``viscosity``: kinematic
    (m²/s, the standard SPH viscosity of Monaghan's form); ``boundary_viscosity``: the same
    coefficient at the walls (0: free slip). ``viscosity_method``: ``"standard"`` (explicit;
    unstable at large coefficients) or ``"weiler2018"`` (Weiler et al. 2018, implicit: stable
    at large coefficients). ``cfl_factor`` scales the CFL step."""

    particle_radius: float
    density0: float = 1000.0
    viscosity: float = 1.0e-6
    boundary_viscosity: float = 1.0e-6
    viscosity_method: str = "standard"
    max_dt: float = 2.0e-3
    min_dt: float = 1.0e-5
    cfl_factor: float = 0.5
    max_density_error_pct: float = 0.1
    max_divergence_error_pct: float = 0.1
    threads: int = 1

    def __post_init__(self) -> None:
        checks = {"particle_radius": 1e-5 <= self.particle_radius <= 0.1,
                  "density0": self.density0 > 0, "viscosity": self.viscosity >= 0,
                  "boundary_viscosity": self.boundary_viscosity >= 0,
                  "viscosity_method": self.viscosity_method in _VISCOSITY_METHODS,
                  "max_dt": 0 < self.min_dt <= self.max_dt <= 0.05,
                  "cfl_factor": 0 < self.cfl_factor <= 1,
                  "max_density_error_pct": 0 < self.max_density_error_pct <= 10,
                  "max_divergence_error_pct": 0 < self.max_divergence_error_pct <= 10,
                  "threads": isinstance(self.threads, int) and self.threads >= 1}
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"SphSettings: out of range: {', '.join(bad)} ({self})")

    @property
    def particle_mass(self) -> float:
        """kg: ρ0·(2r)³, the mass SPlisHSPlasH gives a particle."""
        return self.density0 * (2.0 * self.particle_radius) ** 3


def _scene_json(boundaries: Sequence[Boundary], files: Sequence[Path],
                fluids: Sequence[FluidBlock | FluidParticles], particle_files: Sequence[Path],
                s: SphSettings, gravity: NDArray[np.float64]) -> dict[str, Any]:
    blocks = [f for f in fluids if isinstance(f, FluidBlock)]
    return {
        "Configuration": {
            "particleRadius": s.particle_radius,
            "simulationMethod": _DFSPH,
            "boundaryHandlingMethod": _AKINCI2012,
            "gravitation": [float(x) for x in gravity],
            "timeStepSize": s.max_dt,
            "cflMethod": _CFL,
            "cflFactor": s.cfl_factor,
            "cflMaxTimeStepSize": s.max_dt,
            "cflMinTimeStepSize": s.min_dt,
            "enableZSort": False,
            "stopAt": _FIRST_STOP,
            "pause": False,
            "enablePartioExport": False,
            "enableVTKExport": False,
            "enableRigidBodyExport": False,
            "enableStateExport": False,
            "DFSPH": {
                "minIterations": 2,
                "maxIterations": 100,
                "maxError": s.max_density_error_pct,
                "maxIterationsV": 100,
                "maxErrorV": s.max_divergence_error_pct,
                "enableDivergenceSolver": True,
            },
        },
        "Materials": [{
            "id": "Fluid",
            "density0": s.density0,
            "viscosityMethod": _VISCOSITY_METHODS[s.viscosity_method][0],
            "maxEmitterParticles": 0,
            _VISCOSITY_METHODS[s.viscosity_method][1]: {
                "viscosity": s.viscosity, "viscosityBoundary": s.boundary_viscosity},
        }],
        "RigidBodies": [{
            "geometryFile": str(path),
            "translation": [0.0, 0.0, 0.0],
            "rotationAxis": [1.0, 0.0, 0.0],
            "rotationAngle": 0.0,
            "scale": [1.0, 1.0, 1.0],
            "isDynamic": b.held,
            "isAnimated": b.animated,
            **({"density": _HELD_DENSITY} if b.held else {}),
            "isWall": False,
            "samplingMode": _REGULAR_SAMPLING,
        } for b, path in zip(boundaries, files, strict=True)],
        "FluidBlocks": [{
            "id": "Fluid",
            "denseMode": 0,
            "start": [float(x) - s.particle_radius for x in f.lower],
            "end": [float(x) + s.particle_radius for x in f.upper],
            "translation": [0.0, 0.0, 0.0],
            "scale": [1.0, 1.0, 1.0],
        } for f in blocks],
        "FluidModels": [{
            "id": "Fluid",
            "particleFile": str(path),
            "translation": [0.0, 0.0, 0.0],
            "rotationAxis": [1.0, 0.0, 0.0],
            "rotationAngle": 0.0,
            "scale": [1.0, 1.0, 1.0],
        } for path in particle_files],
    }


def _set_omp_threads(n: int) -> None:
    """``omp_set_num_threads(n)`` on the OpenMP runtime the loaded library uses."""
    import ctypes

    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return
    libs = {line.split()[-1] for line in maps.splitlines()
            if "libgomp" in line or "libomp" in line}
    for lib in sorted(libs):
        try:
            ctypes.CDLL(lib).omp_set_num_threads(ctypes.c_int(n))
        except (OSError, AttributeError):
            continue


@contextlib.contextmanager
def _stdout_to(path: Path) -> Iterator[None]:
    """The process's standard output (file descriptor 1, where the library's console log
    writes) appended to ``path`` for the duration."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(path, "ab") as log:
            os.dup2(log.fileno(), 1)
        yield
    finally:
        with contextlib.suppress(OSError):
            os.fsync(1)
        os.dup2(saved, 1)
        os.close(saved)


def _load(threads: int) -> ModuleType:
    os.environ.setdefault("OMP_NUM_THREADS", str(threads))
    sph = load_splishsplash()
    _set_omp_threads(threads)
    return sph


# SPlisHSPlasH keeps its scene in process-wide singletons: one liquid is open per process.
# A thread that opens one while another thread's is open waits for it to close (two trials
# in the threads of one Dask worker run their liquids one after the other).
_GUARD = threading.Condition()
_OPEN: list[SphLiquid] = []


def _claim(liquid: SphLiquid) -> None:
    with _GUARD:
        while _OPEN and _OPEN[0]._owner != liquid._owner:
            _GUARD.wait()
        if _OPEN:
            raise RuntimeError("one SphLiquid is open in this thread (SPlisHSPlasH keeps its "
                               "scene in singletons): close it first")
        _OPEN.append(liquid)


def _release(liquid: SphLiquid) -> None:
    with _GUARD:
        if liquid in _OPEN:
            _OPEN.remove(liquid)
        _GUARD.notify_all()


def close_this_threads_liquid() -> None:
    """Close the liquid this thread opened, if one is open (a trial's end: lets another
    thread's liquid start)."""
    with _GUARD:
        mine = [q for q in _OPEN if q._owner == threading.get_ident()]
    for q in mine:
        q.close()


class SphLiquid:
    """A SPlisHSPlasH liquid (see the module doc for the contract). Close it (or use it as a
    context manager) to free the library's scene and the temporary files."""

    def __init__(self, boundaries: Sequence[Boundary],
                 fluids: Sequence[FluidBlock | FluidParticles],
                 settings: SphSettings, gravity: ArrayLike = (0.0, 0.0, -9.80665), *,
                 extra_acceleration: ExtraAcceleration | None = None) -> None:
        names = [b.name for b in boundaries]
        if len(set(names)) != len(names):
            raise ValueError(f"boundary names must be unique; got {names}")
        if not fluids:
            raise ValueError("a liquid needs at least one fluid block")
        for f in fluids:
            if isinstance(f, FluidParticles):
                continue
            counts = np.round((np.asarray(f.upper) - np.asarray(f.lower))
                              / (2.0 * settings.particle_radius))
            if np.any(counts < 2):
                raise ValueError(f"fluid block {f} holds fewer than 2 particles of radius "
                                 f"{settings.particle_radius} m along an axis")
        self.settings = settings
        self.extra_acceleration = extra_acceleration
        self._gravity = _vec3(gravity, "gravity")
        self._sph = _load(settings.threads)
        self._owner = threading.get_ident()
        self._closed = True
        self._final: tuple[NDArray[Any], ...] = (np.zeros((0, 3)), np.zeros((0, 3)),
                                                 np.zeros(0, dtype=np.int64))
        self._final_time = 0.0
        _claim(self)
        self._dir = Path(tempfile.mkdtemp(prefix="articutool-sph-"))
        self._closed = False
        try:
            files = []
            for i, b in enumerate(boundaries):
                path = self._dir / f"boundary{i}.obj"
                b.write_obj(path)
                files.append(path)
            particle_files = []
            for i, f in enumerate(fluids):
                if isinstance(f, FluidParticles):
                    path = self._dir / f"fluid{i}.pda"
                    f.write_pda(path)
                    particle_files.append(path)
            scene_file = self._dir / "scene.json"
            scene_file.write_text(json.dumps(_scene_json(boundaries, files, fluids,
                                                         particle_files, settings,
                                                         self._gravity), indent=1))
            self._log = self._dir / "splishsplash.log"
            self._base = self._sph.Exec.SimulatorBase()
            with _stdout_to(self._log):
                self._base.init(useGui=False, sceneFile=str(scene_file), useCache=False,
                                outputDir=str(self._dir / "output"), initialPause=False,
                                stopAt=_FIRST_STOP)
                self._base.initSimulation()
                self._base.runSimulation()  # deferredInit (boundary models), one first step
            self._base.setValueFloat(self._base.STOP_AT, -1.0)  # never stop from now on
            self._sim = self._sph.Simulation.getCurrent()
            self._tm = self._sph.TimeManager.getCurrent()
            self._fluid = self._sim.getFluidModel(0)
            self._boundary_index = {b.name: i for i, b in enumerate(boundaries)}
            self._animated = {b.name for b in boundaries if b.animated or b.held}
            self._held = {b.name: _Held(self._rigid_body(b.name)) for b in boundaries
                          if b.held}
            self._pose_held()  # back where the mesh lies: the first step moved them
            self.particle_mass = float(self._fluid.getMass(0))
        except BaseException:
            shutil.rmtree(self._dir, ignore_errors=True)
            _release(self)
            raise

    # -- lifetime ---------------------------------------------------------------------------

    def close(self) -> None:
        """Free the library's scene and remove the temporary directory (idempotent). The
        particles' state at this moment stays readable (positions, velocities, ids), whoever
        closes it: a world whose liquid another world of the thread closed keeps its state."""
        if self._closed:
            return
        self._final = (self.positions(), self.velocities(), self.particle_ids())
        self._final_time = self.time
        self._closed = True
        try:
            with _stdout_to(self._log):
                self._base.cleanup()
        finally:
            shutil.rmtree(self._dir, ignore_errors=True)
            _release(self)

    def __enter__(self) -> SphLiquid:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this SphLiquid is closed")

    # -- state ------------------------------------------------------------------------------

    @property
    def backend(self) -> dict[str, str]:
        """The library and its version (for a result's provenance)."""
        return {"backend": "SPlisHSPlasH (pysplishsplash)", "version": library_version()}

    @property
    def time(self) -> float:
        """Simulated time (s; once closed: at the close)."""
        if self._closed:
            return self._final_time
        return float(self._tm.getTime())

    @property
    def last_dt(self) -> float:
        """The last library step's size (s)."""
        return float(self._tm.getTimeStepSize())

    @property
    def n_particles(self) -> int:
        """Particles still simulated (removed ones excluded; once closed: at the close)."""
        if self._closed:
            return len(self._final[0])
        return int(self._fluid.numActiveParticles())

    @property
    def gravity(self) -> NDArray[np.float64]:
        """The (apparent) gravity the liquid feels now (m/s²)."""
        return self._gravity.copy()

    def _field(self, name: str) -> NDArray[Any]:
        return np.asarray(self._fluid.getFieldBuffer(name))

    @property
    def closed(self) -> bool:
        """The library's scene is freed (by close(), or by another world of this thread)."""
        return self._closed

    def positions(self) -> NDArray[np.float64]:
        """Positions (m) of the simulated particles, (n_particles, 3), a copy (once closed:
        those it was closed with)."""
        if self._closed:
            return self._final[0].copy()
        return np.array(self._field("position")[: self.n_particles], dtype=float)

    def velocities(self) -> NDArray[np.float64]:
        """Velocities (m/s) of the simulated particles, (n_particles, 3), a copy (once
        closed: those it was closed with)."""
        if self._closed:
            return self._final[1].copy()
        return np.array(self._field("velocity")[: self.n_particles], dtype=float)

    def particle_ids(self) -> NDArray[np.int64]:
        """Each simulated particle's id (stable over the run), aligned with positions()
        (once closed: those it was closed with)."""
        if self._closed:
            return self._final[2].copy()
        return np.array(self._field("id")[: self.n_particles], dtype=np.int64)

    # -- driving ----------------------------------------------------------------------------

    def set_velocities(self, v: ArrayLike) -> None:
        """Give the simulated particles these velocities (m/s, (n_particles, 3), in the order
        the particles were given, i.e. by id; the library reorders its own arrays): a liquid
        handed over from another scene keeps its motion."""
        self._check_open()
        n = self.n_particles
        a = np.asarray(v, dtype=float)
        if a.shape != (n, 3) or not np.all(np.isfinite(a)):
            raise ValueError(f"velocities must be ({n}, 3) finite; got {a.shape}")
        ids = self.particle_ids()
        self._field("velocity")[:n] = a[np.searchsorted(np.sort(ids), ids)]

    def set_gravity(self, g: ArrayLike) -> None:
        """The (apparent) gravity from the next step on (m/s², 3 numbers)."""
        self._check_open()
        self._gravity = _vec3(g, "gravity")
        self._sim.setVec3ValueReal(self._sim.GRAVITATION, self._gravity)

    def _rigid_body(self, name: str) -> Any:
        return self._sim.getBoundaryModel(self._boundary_index[name]).getRigidBodyObject()

    def set_boundary_pose(self, name: str, position: ArrayLike, rotation: ArrayLike,
                          linear_velocity: ArrayLike = (0.0, 0.0, 0.0),
                          angular_velocity: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Pose of an animated or held boundary from the next step on: ``position`` (m) and
        ``rotation`` (3×3, scene ← mesh) map its mesh into the scene; the velocities (m/s,
        rad/s, scene frame, angular about ``position``) enter the pressure solve."""
        self._check_open()
        if name not in self._boundary_index:
            raise KeyError(f"no boundary {name!r}; have {sorted(self._boundary_index)}")
        if name not in self._animated:
            raise ValueError(f"boundary {name!r} is neither animated nor held (declare "
                             "animated=True or held=True)")
        R = np.asarray(rotation, dtype=float)
        if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6):
            raise ValueError("rotation must be a 3×3 rotation matrix")
        p = _vec3(position, "position")
        v, w = _vec3(linear_velocity, "linear_velocity"), _vec3(angular_velocity,
                                                                "angular_velocity")
        if name in self._held:
            self._held[name].hold(p, R, v, w)
            self._pose_held()
            return
        _place(self._rigid_body(name), p, Rotation.from_matrix(R), v, w)
        self._base.updateBoundaryParticles(False)

    def _pose_held(self) -> None:
        """Put every held body back at its pose and velocities (the library's rigid-body
        solver moved it in the last step)."""
        if self._held:
            for h in self._held.values():
                h.apply()
            self._base.updateBoundaryParticles(False)

    def held_force(self, name: str) -> NDArray[np.float64]:
        """The liquid's force (N, scene frame) on the held boundary ``name``: its mean over
        the steps since the last call (zero if none)."""
        self._check_open()
        if name not in self._held:
            raise ValueError(f"boundary {name!r} is not held (declare held=True)")
        return self._held[name].take()

    def step(self) -> float:
        """One library step (its CFL size); returns the step's size (s)."""
        self._check_open()
        self._pose_held()
        self._base.timeStepNoGUI()
        dt = self.last_dt
        for h in self._held.values():
            h.read(dt)
        if self.extra_acceleration is not None and self.n_particles:
            n = self.n_particles
            v = self._field("velocity")
            x = np.array(self._field("position")[:n], dtype=float)
            a = np.asarray(self.extra_acceleration(x, np.array(v[:n], dtype=float)), dtype=float)
            if a.shape != (n, 3) or not np.all(np.isfinite(a)):
                raise ValueError(f"extra_acceleration must return ({n}, 3) finite; got "
                                 f"{a.shape}")
            v[:n] += dt * a
        return dt

    def step_to(self, t: float) -> int:
        """Advance until the simulated time reaches ``t`` (s); returns the steps taken."""
        self._check_open()
        if not math.isfinite(t):
            raise ValueError(f"t must be finite; got {t}")
        steps = 0
        with _stdout_to(self._log):
            while self.time < t - 1e-12:
                self.step()
                steps += 1
        return steps

    def remove_particles(self, mask: ArrayLike) -> int:
        """Stop simulating the particles where ``mask`` (n_particles booleans, aligned with
        positions()) is true; returns how many were removed. The rest keep their ids."""
        self._check_open()
        n = self.n_particles
        m = np.asarray(mask, dtype=bool)
        if m.shape != (n,):
            raise ValueError(f"mask must be ({n},) booleans; got {m.shape}")
        k = int(m.sum())
        if k == 0:
            return 0
        order = np.concatenate([np.flatnonzero(~m), np.flatnonzero(m)])
        size = int(self._fluid.numParticles())
        for i in range(int(self._fluid.numberOfFields())):
            buf = np.asarray(self._fluid.getFieldBuffer(i))
            if buf.ndim >= 1 and buf.shape[0] == size:
                buf[:n] = buf[:n][order]
        x, v = self._field("position"), self._field("velocity")
        keep = n - k
        spacing = 10.0 * self._sim.getSupportRadius()
        park = np.arange(keep, n, dtype=float)[:, None] * spacing
        x[keep:n] = _PARK + np.hstack([park, np.zeros((k, 2))])
        v[keep:n] = 0.0
        self._fluid.setNumActiveParticles(keep)
        return k


def _place(rb: Any, position: NDArray[np.float64], rotation: Rotation,
           velocity: NDArray[np.float64], angular_velocity: NDArray[np.float64]) -> None:
    """Pose a library rigid body and move its mesh (not yet its boundary particles)."""
    rb.setPosition(position)
    rb.setRotation(rotation.as_quat())  # (x, y, z, w), Eigen's coeffs
    rb.setVelocity(velocity)
    rb.setAngularVelocity(angular_velocity)
    rb.updateMeshTransformation()


class _Held:
    """A held body: its rigid body in the library, the state it is put back to before every
    step, and the liquid's impulse on it since the last read.

    The library's rigid body is posed by its centre of mass and principal axes; the mesh's
    pose maps through them (``com``: the centre of mass in the mesh's frame, ``axes``: the
    principal axes' rotation in it), read once from the body as built."""

    def __init__(self, rb: Any) -> None:
        self.rb = rb
        self.mass = float(rb.getMass())
        R_mesh = np.array(rb.getWorldSpaceRotation(), dtype=float)
        p_mesh = np.array(rb.getWorldSpacePosition(), dtype=float)
        self.com = R_mesh.T @ (np.array(rb.getPosition(), dtype=float) - p_mesh)
        self.axes = (Rotation.from_matrix(R_mesh).inv()
                     * Rotation.from_quat(np.array(rb.getRotation(), dtype=float)))
        self.hold(np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3))
        self.impulse, self.duration = np.zeros(3), 0.0

    def hold(self, p: NDArray[np.float64], R: NDArray[np.float64], v: NDArray[np.float64],
             w: NDArray[np.float64]) -> None:
        """Keep the mesh at pose (``p``, ``R``) with velocities ``v`` (at ``p``) and ``w``:
        the library body's state, computed once."""
        arm = R @ self.com
        self.v0 = v + np.cross(w, arm)  # the centre of mass's velocity
        self.state = (p + arm, Rotation.from_matrix(R) * self.axes, self.v0, w)

    def apply(self) -> None:
        _place(self.rb, *self.state)

    def read(self, dt: float) -> None:
        """Add the step's impulse, read from the velocity the library gave the body."""
        v1 = np.array(self.rb.getVelocity(), dtype=float)
        self.impulse += self.mass * ((v1 - self.v0) - dt * _PBD_GRAVITY)
        self.duration += dt

    def take(self) -> NDArray[np.float64]:
        f = self.impulse / self.duration if self.duration > 0 else np.zeros(3)
        self.impulse, self.duration = np.zeros(3), 0.0
        return f


# -- momentum balance (pure) -------------------------------------------------------------------

def momentum_balance_force(mass: ArrayLike, accelerations: ArrayLike,
                           gravity: ArrayLike) -> NDArray[np.float64]:
    """Force (N) a liquid's particles exert on what holds them: ``Σ m (g − a_i)``.

    ``mass``: one particle mass (kg) or one per particle; ``accelerations`` (N, 3) m/s²;
    ``gravity`` (3,) or one per particle (N, 3), the (apparent) gravity of the frame the
    accelerations are in."""
    a = np.asarray(accelerations, dtype=float).reshape(-1, 3)
    m = np.broadcast_to(np.asarray(mass, dtype=float), (a.shape[0],))
    g = np.asarray(gravity, dtype=float).reshape(-1, 3)
    return (m[:, None] * (g - a)).sum(axis=0)


def momentum_balance_torque(mass: ArrayLike, positions: ArrayLike, accelerations: ArrayLike,
                            gravity: ArrayLike, point: ArrayLike) -> NDArray[np.float64]:
    """Torque (N·m) about ``point`` of the same forces: ``Σ (x_i − c) × m (g − a_i)``."""
    a = np.asarray(accelerations, dtype=float).reshape(-1, 3)
    x = np.asarray(positions, dtype=float).reshape(-1, 3)
    m = np.broadcast_to(np.asarray(mass, dtype=float), (a.shape[0],))
    g = np.asarray(gravity, dtype=float).reshape(-1, 3)
    c = np.asarray(point, dtype=float).reshape(3)
    return np.cross(x - c, m[:, None] * (g - a)).sum(axis=0)


def rotating_frame_acceleration(omega: ArrayLike, omega_dot: ArrayLike,
                                origin: ArrayLike = (0.0, 0.0, 0.0)) -> ExtraAcceleration:
    """The fictitious accelerations of a frame turning at ``omega`` (rad/s, in the frame) with
    ``omega_dot`` (rad/s²) about ``origin``: ``−ω̇×r − 2ω×v − ω×(ω×r)``, ``r = x − origin``
    (the frame's translation belongs in the apparent gravity)."""
    w, wd = _vec3(omega, "omega"), _vec3(omega_dot, "omega_dot")
    o = _vec3(origin, "origin")

    def accel(x: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        r = x - o
        return -np.cross(wd, r) - 2.0 * np.cross(w, v) - np.cross(w, np.cross(w, r))

    return accel
