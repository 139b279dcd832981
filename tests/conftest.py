"""Shared test fixtures and helpers.

Fixtures: ``spec`` and ``scene`` — the packaged hardware spec and scene, loaded once per
session (both are frozen models, so sharing them is safe).

Helpers, imported where a module-level helper or class needs them (``from conftest import
free_port``):

- :func:`free_port` — a loopback TCP port that nobody listens on now;
- :func:`run_cli` — the ``articutool`` command as a user runs it, in its own process;
- :func:`minimal_env` — the environment of a bare shell (no venv variables, no display);
- :func:`assert_refused` — bad input: exit 2, the named fields in stderr, no traceback;
- :func:`wait_until` — poll a condition; the deadline only bounds a failing test;
- :func:`drop_off_the_table` — move a food item that spilled on the table to just above the
  floor beside it (water deposits where it lands, so a table-then-floor spill is staged);
- :func:`trial_record` — an experiment's trial record built by hand (the fields a test names,
  neutral values for the rest), validated as a trial log line is.
"""

from __future__ import annotations

import functools
import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path

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


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nobody listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


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


def wait_until(pred: Callable[[], object], timeout: float = 5.0, period: float = 0.01) -> bool:
    """Poll ``pred`` every ``period`` s until it is true (True) or ``timeout`` s pass (False).
    The timeout bounds a failing test on a loaded machine; no timing is asserted."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(period)
    return bool(pred())


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

    from articutool.experiments.records import CONDITIONS, OUTCOMES, TrialRecord

    line: dict[str, object] = {"experiment": experiment, "trial": trial, "repeat": 0,
                               "seed": 0, "wall_time_s": 1.0, "pid": 1, "error": None}
    for name, f in CONDITIONS[experiment].model_fields.items():
        if f.is_required():
            line[name] = _CONDITION[name]
    if not fields.get("error"):
        for name, f in OUTCOMES[experiment].model_fields.items():
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
