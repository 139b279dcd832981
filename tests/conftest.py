"""Shared test fixtures and helpers.

Fixtures: ``spec`` and ``scene`` — the packaged hardware spec and scene, loaded once per
session (both are frozen models, so sharing them is safe).

Helpers, imported where a module-level helper or class needs them (``from conftest import
free_port``):

- :func:`free_port` — a loopback TCP port that nobody listens on now;
- :func:`ros_domain_id` — a ROS 2 domain of this test process's own (pytest-xdist workers
  never share one);
- :func:`run_cli` — the ``articutool`` command as a user runs it, in its own process;
- :func:`minimal_env` — the environment of a bare shell (no venv variables, no display);
- :func:`assert_refused` — bad input: exit 2, the named fields in stderr, no traceback;
- :func:`wait_until` — poll a condition; the deadline only bounds a failing test;
- :func:`drop_off_the_table` — move a food item that spilled on the table to just above the
  floor beside it (water deposits where it lands, so a table-then-floor spill is staged);
- :func:`descendants` — the processes below a process, read from ``/proc``;
- :func:`trial_record` — an experiment's trial record built by hand (the fields a test names,
  neutral values for the rest), validated as a trial log line is;
- :class:`PerfectArm` — an arm driver (:class:`~articutool.planning.pc_arm.ArmDriver`) that
  follows every commanded trajectory exactly, on a clock the test advances (no physics).
"""

from __future__ import annotations

import ast
import contextlib
import functools
import json
import os
import random
import resource
import signal
import socket
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

import hypothesis
import pytest

from articutool.spec import Spec, load_spec

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
EXAMPLES = ROOT / "examples"
# The ``articutool`` command, as the console script runs it.
CLI = [sys.executable, "-m", "articutool"]


@functools.cache
def packaged_spec() -> Spec:
    """The packaged hardware spec, parsed once (for constants a module needs at import, such
    as a hypothesis strategy's bounds; tests take the ``spec`` fixture)."""
    return load_spec()


# Hypothesis' per-example deadline (200 ms) is a wall-clock claim: no test asserts timing.
hypothesis.settings.register_profile("articutool", deadline=None)
hypothesis.settings.load_profile("articutool")


FLOODS = "floods"


@functools.cache
def _flood_tests(module: str) -> frozenset[str]:
    """The test functions of ``module`` (a path from the root) marked ``@pytest.mark.floods``,
    read from its source (pytest-xdist's controller does not collect the tests)."""
    path = ROOT / module
    if path.suffix != ".py" or not path.is_file():
        return frozenset()
    tree = ast.parse(path.read_text(), module)
    return frozenset(f.name for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
                     and any(ast.unparse(d) == "pytest.mark.floods" for d in f.decorator_list))


def pytest_configure(config: pytest.Config) -> None:
    """Ctrl-C reaches the processes the tests start: a runner started as a background job of a
    non-interactive shell (``make test &`` in a script) inherits SIGINT ignored, and so would
    every process it starts, whose Ctrl-C tests would then wait in vain."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _terminated)


def descendants(pid: int) -> list[int]:
    """The processes below ``pid`` (children first), read from ``/proc``."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue  # the process ended while the table was read
        ppid = int(text[text.rindex(")") + 2:].split()[1])
        children.setdefault(ppid, []).append(int(stat.parent.name))
    out, todo = [], [pid]
    while todo:
        kids = children.get(todo.pop(), [])
        out += kids
        todo += kids
    return out


def _terminated(signum: int, frame: object) -> None:
    """A runner told to stop (SIGTERM: a CI timeout, ``kill``) takes the processes its tests
    started with it (tools, nodes, clients — they would otherwise keep running and loading the
    machine), then ends as SIGTERM ends a process."""
    for pid in descendants(os.getpid()):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGTERM)


# A module missing from tests/module_costs.json counts this many seconds a test.
UNMEASURED_TEST_S = 1.0


@functools.cache
def _module_costs() -> dict[str, float]:
    """Each module's measured test time (``tests/module_costs.json``, written by
    ``tests/module_costs.py``): the order the scheduler sends modules in, costliest first."""
    path = ROOT / "tests" / "module_costs.json"
    return json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}


def pytest_xdist_make_scheduler(config: pytest.Config, log):  # type: ignore[no-untyped-def]
    """``--dist loadgroup``: each module's tests together on one worker (module fixtures are
    built once), the tests marked ``floods`` (link floods, a CPU hog beside the real-time
    loop: two must not load the machine at once) one after another on one worker, sent
    first (they are long), then the modules costliest first (``tests/module_costs.json``), so
    that no long module starts while the other workers run out of work. pytest-xdist's own
    loadgroup reads groups from the node ids, which pytest 9.2 no longer lets a plugin
    change."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ModulesAndFloods(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module, _, rest = nodeid.partition("::")
            name = rest.split("::")[-1].split("[")[0]
            return FLOODS if name in _flood_tests(module) else module

        def _assign_work_unit(self, node):  # type: ignore[no-untyped-def]
            if not getattr(self, "_ordered", False):
                self._ordered = True
                cost = _module_costs()
                for scope in sorted(self.workqueue, key=lambda s: -cost.get(
                        s, len(self.workqueue[s]) * UNMEASURED_TEST_S)):
                    self.workqueue.move_to_end(scope)
            if FLOODS in self.workqueue:
                self.workqueue.move_to_end(FLOODS, last=False)
            super()._assign_work_unit(node)

    return ModulesAndFloods(config, log)


# When the test now running started, on the CPU clock; each test's CPU seconds (controller).
_CPU_AT_START = pytest.StashKey[float]()
_CPU_BY_TEST: dict[str, float] = {}


def _cpu_s() -> float:
    """CPU seconds (user + system) of this process and of its children it has waited for."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):  # type: ignore[no-untyped-def]
    """Stamp the CPU clock as a test starts (its setup, call and teardown are charged to it)."""
    item.stash[_CPU_AT_START] = _cpu_s()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):  # type: ignore[no-untyped-def]
    """The teardown's report carries the test's CPU seconds (``user_properties``, which
    pytest-xdist sends to the controller)."""
    outcome = yield
    if call.when == "teardown" and _CPU_AT_START in item.stash:
        outcome.get_result().user_properties.append(
            ("cpu_s", round(_cpu_s() - item.stash[_CPU_AT_START], 3)))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Collect each test's CPU seconds where the summary is printed (the controller)."""
    for key, value in report.user_properties:
        if key == "cpu_s" and report.when == "teardown":
            _CPU_BY_TEST[report.nodeid] = float(value)


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:  # type: ignore[no-untyped-def]
    """With ``--durations=N``: beside pytest's wall-clock list, the N tests that cost the most
    CPU (user + system, this worker's process and the processes the test started and waited
    for; a module fixture is charged to its first test) and the suite's total: the suite is
    CPU-bound, so its CPU, not the waits, sets its wall time on a given number of cores."""
    n = config.getoption("durations", None)
    if not n or not _CPU_BY_TEST:
        return
    tr = terminalreporter
    tr.write_sep("=", f"most CPU {n} (user + system s, the test and its reaped children)")
    for nodeid, cpu in sorted(_CPU_BY_TEST.items(), key=lambda kv: -kv[1])[:n]:
        tr.write_line(f"{cpu:8.2f}s cpu  {nodeid}")
    modules: Counter[str] = Counter()
    for nodeid, cpu in _CPU_BY_TEST.items():
        modules[nodeid.partition("::")[0]] += cpu
    top = ", ".join(f"{m.removeprefix('tests/')} {c:.0f}" for m, c in modules.most_common(8))
    tr.write_line(f"{sum(_CPU_BY_TEST.values()):.0f} CPU s in {len(_CPU_BY_TEST)} tests; "
                  f"costliest modules (CPU s): {top}")


@pytest.fixture(scope="session")
def spec() -> Spec:
    """The packaged hardware spec."""
    return packaged_spec()


@pytest.fixture(scope="session")
def scene():  # type: ignore[no-untyped-def]
    """The packaged scene (``data/scene.toml``); imported here, not at the top, so that
    collecting the tests does not load coal."""
    from articutool.arm.scene import Scene

    return Scene.load()


STUDIES = Path(__file__).resolve().parents[1] / "studies"


def import_study(name: str):  # type: ignore[no-untyped-def]
    """The module ``studies/<name>.py``, imported with ``studies/`` on the path only while it
    loads (usable inside hypothesis tests, where function-scoped fixtures are not)."""
    import importlib

    sys.path.insert(0, str(STUDIES))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(STUDIES))


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nobody listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def ros_domain_id(salt: int = 0) -> int:
    """A ROS 2 domain id for this test process: one of [120, 220] (away from the default 0),
    drawn from the process id (another run on this host most likely draws another) among the
    ids of this pytest-xdist worker alone (worker i of n: the ids ≡ i mod n), so nodes that
    two workers start at once never see each other. ``salt`` 1, 2, … gives other ids of
    the same worker."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    i = int(worker[2:]) if worker[2:].isdigit() else 0
    n = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
    ids = range(120 + i % n, 221, n)
    return ids[(random.Random(os.getpid()).randrange(len(ids)) + salt) % len(ids)]


def minimal_env(**extra: str) -> dict[str, str]:
    """A bare shell's environment: the system PATH, a HOME, no display (``MPLBACKEND=Agg``),
    and the package on ``PYTHONPATH`` (no venv variables)."""
    return {"PATH": "/usr/bin:/bin", "MPLBACKEND": "Agg", "PYTHONPATH": str(SRC),
            "HOME": os.environ.get("HOME", "/tmp"), **extra}


def run_cli(*args: str, timeout: float = 300.0, env: Mapping[str, str] | None = None,
            cwd: Path | None = None, stdout: int | None = subprocess.PIPE,
            input: str | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``articutool ARGS`` in a child process (``python -m articutool``, what the console
    script runs) and return it finished; ``timeout`` only bounds a hang."""
    if env is None:
        env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    return subprocess.run([*CLI, *args], stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=timeout, cwd=cwd,
                          env=dict(env), input=input)


def assert_refused(proc: subprocess.CompletedProcess[str], *words: str) -> None:
    """Bad input: exit 2, every word of ``words`` in stderr, and no traceback."""
    err = proc.stderr
    assert proc.returncode == 2, (proc.stdout, err)
    assert "Traceback" not in (proc.stdout or "") + err and "internal error" not in err, err
    for w in words:
        assert w in err, err


# A shared machine under load (several sessions, both cores busy with the suite's workers)
# runs a test's processes many times slower than an idle one: deadlines that only bound a
# failing test are stretched by this factor.
DEADLINE_SLACK = 6.0


def wait_until(pred: Callable[[], object], timeout: float = 5.0, period: float = 0.01) -> bool:
    """Poll ``pred`` every ``period`` s until it is true (True) or ``DEADLINE_SLACK`` ×
    ``timeout`` s pass (False). The deadline bounds a failing test on a loaded machine; no
    timing is asserted (a passing test returns as soon as ``pred`` holds)."""
    end = time.monotonic() + DEADLINE_SLACK * timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(period)
    return bool(pred())


class PerfectArm:
    """An :class:`~articutool.planning.pc_arm.ArmDriver` without physics: the arm joints are
    the commanded trajectory's reference at ``t`` (advanced by :meth:`advance`), so a motion
    ends exactly where it was planned to; the wrist stays at ``wrist``. It refuses a point
    outside the arm's joint limits, as the servos' driver does."""

    def __init__(self, spec: Spec, q_arm, wrist=(0.0, 0.0)) -> None:  # type: ignore[no-untyped-def]
        import numpy as np

        self.spec, self.t = spec, 0.0
        self.q = np.concatenate([np.asarray(q_arm, dtype=float), np.asarray(wrist, dtype=float)])
        self.followed: list = []
        self._traj = None
        self._t0 = 0.0

    def joint_positions(self):  # type: ignore[no-untyped-def]
        return self.q.copy()

    def follow(self, trajectory) -> None:  # type: ignore[no-untyped-def]
        import numpy as np

        from articutool.trajectory import JointTrajectory

        names = tuple(self.spec.arm.joint_names)
        idx = [trajectory.joint_names.index(n) for n in names]
        arm = JointTrajectory(names, trajectory.times, trajectory.positions[:, idx],
                              trajectory.velocities[:, idx])
        lo, hi = self.spec.arm.lower, self.spec.arm.upper
        if np.any((arm.positions < lo - 1e-9) | (arm.positions > hi + 1e-9)):
            raise ValueError("trajectory outside the arm's joint limits")
        self.followed.append(arm)
        self._traj, self._t0 = arm, self.t

    def stop(self) -> None:
        self._traj = None

    @property
    def busy(self) -> bool:
        return self._traj is not None

    def advance(self, dt: float) -> None:
        """Let ``dt`` seconds pass: the arm moves along what it follows."""
        self.t += dt
        if self._traj is not None:
            pos, _ = self._traj.sample(self.t - self._t0)
            self.q[:6] = pos
            if self.t - self._t0 >= self._traj.duration:
                self._traj = None


def drop_off_the_table(world) -> int:  # type: ignore[no-untyped-def]
    """Move the first food item now on the table to 5 cm above the floor beside the table, at
    rest (the world's sleeping must be off: a sleeping body does not move); returns it."""
    import numpy as np

    from articutool.sim import accounting as acc

    on_table = np.flatnonzero(world.ledger.codes == acc.TABLE)
    assert on_table.size, "nothing spilled on the table"
    k = int(on_table[0])
    m, d = world.model, world.data
    j = m.body(world.layout.food_bodies[k]).jntadr[0]
    qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
    d.qpos[qa:qa + 3] = (-0.2, 0.0, world.scene.get("ground").xyz[2] + 0.05)
    d.qvel[va:va + 6] = 0.0
    return k


_NEUTRAL: dict[object, object] = {float: 0.0, int: 0, bool: True, str: ""}
_CONDITION = {"food": "pecans", "system": "articutool", "goal": "g", "condition": "control",
              "load_g": 5.0}


def trial_record(experiment: str, trial: int = 0, **fields: object):  # type: ignore[no-untyped-def]
    """A :class:`~articutool.experiments.records.TrialRecord` of ``experiment`` with the
    given condition and outcome ``fields`` (``error``: a trial that raised, no outcome); every
    other required field is neutral (0, "", empty, completed)."""
    import typing

    from articutool.experiments.records import TrialRecord
    from articutool.experiments.unit import unit

    line: dict[str, object] = {"experiment": experiment, "trial": trial, "repeat": 0,
                               "seed": 0, "wall_time_s": 1.0, "pid": 1, "error": None}
    for name, f in unit(experiment).condition.model_fields.items():
        if f.is_required():
            line[name] = _CONDITION[name]
    if not fields.get("error"):
        for name, f in unit(experiment).outcome.model_fields.items():
            if f.is_required() and name not in line:
                kind = typing.get_origin(f.annotation) or f.annotation
                line[name] = {dict: {}, list: []}.get(kind, _NEUTRAL.get(kind))
    return TrialRecord.from_log({**line, **fields})


# Test modules written for the spheres' placed water: their expectations are the measured
# behaviour of the MuJoCo spheres (docs/food.md), so they run with ``load_model = "spheres"``
# (the comparison option). The liquid's own tests (tests/test_liquid_*.py) use the default.
SPHERE_WATER_MODULES = frozenset({
    "test_contact_params", "test_experiment_scaling", "test_experiments_protocols",
    "test_experiments_runner", "test_feeding_sim", "test_ros2_verify",
    "test_shedding_physics", "test_sim_physics", "test_verify_food", "test_viewer",
    "test_water_model"})


@pytest.fixture(autouse=True)
def _sphere_water(request, monkeypatch):  # type: ignore[no-untyped-def]
    """In :data:`SPHERE_WATER_MODULES`, the packaged physics' placed water is spheres."""
    if request.module.__name__.rsplit(".", 1)[-1] not in SPHERE_WATER_MODULES:
        yield
        return
    from articutool.sim import params as sim_params

    load = sim_params.PhysicsParams.load.__func__

    def spheres(cls, path=None):  # type: ignore[no-untyped-def]
        p = load(cls, path)
        w = p.foods.get("water")
        if path is None and isinstance(w, sim_params.Liquid):
            w = w.model_copy(update={"load_model": "spheres"})
            p = p.model_copy(update={"foods": {**p.foods, "water": w}})
        return p

    monkeypatch.setattr(sim_params.PhysicsParams, "load", classmethod(spheres))
    yield


@pytest.fixture(autouse=True, scope="module")
def _close_this_threads_liquid() -> Iterator[None]:
    """A module that leaves a world with a liquid load open (the process holds one liquid
    solver) does not stop the next module from opening its own."""
    yield
    if "articutool.sim.sph_scene" in sys.modules:
        sys.modules["articutool.sim.sph_scene"].close_this_threads_liquid()
