"""Closed-loop shedding primitives (thesis §7.1.2's future work) on the tool's own runtime.

The runtime runs the primitive at 50 Hz on the simulated wrist (``SimWrist``: motor lag,
velocity limits) and reads the simulated F/T sensor (tared, with noise) through its driver;
the load is an external force on the sensor that the test changes as food would leave it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from articutool.tool.api import Mode
from articutool.tool.drivers.sim import SimWrist
from articutool.tool.runtime import ToolRuntime
from conftest import packaged_spec

SPEC = packaged_spec()
DT = SPEC.wrist.period
G = SPEC.imu.gravity


def _weight(grams: float) -> tuple[float, float, float]:
    return (0.0, 0.0, -grams / 1000.0 * G)


def make(ft=True, seed=0):
    sim = SimWrist(SPEC, seed=seed)
    rt = ToolRuntime(SPEC, sim.motor_driver(), sim.imu_driver(),
                     sim.ft_driver() if ft else None, clock=sim.clock)
    rt.open()
    for _ in range(round(0.5 / DT)):  # tare (empty) and a first joint state
        sim.step(DT)
        rt.tick(sim.time, DT)
    return sim, rt


def run_primitive(sim, rt, name, params, load_of_time_and_roll, limit_s=30.0):
    """Start the primitive; each tick the load is ``load(t, roll)`` grams. Returns (status,
    seconds run, max |roll| from the start)."""
    sim.set_external_wrench(_weight(load_of_time_and_roll(0.0, 0.0)))
    ok, msg = rt.start_primitive(name, params)
    assert ok, msg
    t0, r0, peak = sim.time, float(sim.q[1]), 0.0
    while rt.state().mode is Mode.PRIMITIVE and sim.time - t0 < limit_s:
        roll = float(sim.q[1]) - r0
        peak = max(peak, abs(roll))
        sim.set_external_wrench(_weight(load_of_time_and_roll(sim.time - t0, roll)))
        sim.step(DT)
        rt.tick(sim.time, DT)
    return rt.primitive_status(), sim.time - t0, peak


VIB = "VIBRATE_ROLL_UNTIL_STABLE"


def test_vibrate_stops_when_the_measured_load_stops_changing():
    sim, rt = make()
    # Food leaves during the first second (10 g → 4 g), then the rest stays.
    st, took, _ = run_primitive(sim, rt, VIB, [8.0, 0.05, 5.0, 0.25, 0.2],
                                lambda t, r: 4.0 + 6.0 * max(0.0, 1.0 - t))
    assert st.done and st.success, st.message
    assert "load stable" in st.message
    # Stable from t = 1 s: the windows ending at 1.25 and 1.5 s agree; far before the 5 s bound.
    assert 1.2 < took < 2.5
    assert "4.0" in st.message or "3.9" in st.message or "4.1" in st.message


def test_vibrate_stops_by_its_time_bound_when_the_load_never_settles():
    sim, rt = make()
    # The load keeps changing by 2 g/s: no two windows agree within 0.2 g.
    st, took, _ = run_primitive(sim, rt, VIB, [8.0, 0.05, 3.0, 0.25, 0.2],
                                lambda t, r: 10.0 - 2.0 * t)
    assert st.done and st.success
    assert "time bound" in st.message
    assert 3.0 <= took < 3.0 + 1.0  # the bound, then the short return


def test_tilt_stops_once_the_load_drops_to_the_target():
    sim, rt = make()
    # Food slides off past 0.3 rad of roll (8 g → 2 g); target 3 g, steps of 0.2 rad.
    state = {"g": 8.0}

    def load(t, roll):
        if abs(roll) > 0.3:
            state["g"] = 2.0
        return state["g"]

    st, _, peak = run_primitive(sim, rt, "TILT_UNTIL_LOAD", [0.2, 1.0, 1.0, 3.0, 0.2], load)
    assert st.done and st.success, st.message
    assert "load at target after 2 tilts" in st.message
    assert 0.35 < peak < 0.45  # the second step (0.4 rad), never the 1.0 rad bound
    assert abs(sim.q[1]) < 0.05  # rolled back


def test_tilt_stops_at_its_bound_when_the_load_stays():
    sim, rt = make()
    st, _, peak = run_primitive(sim, rt, "TILT_UNTIL_LOAD", [0.25, 0.75, 1.0, 3.0, 0.2],
                                lambda t, r: 8.0)
    assert st.done and st.success
    assert "bound reached" in st.message and "after 3 tilts" in st.message
    assert peak == pytest.approx(0.75, abs=0.03)


@pytest.mark.parametrize(("name", "params", "field"), [
    (VIB, [8.0, 0.05, 5.0, 0.05, 0.2], "window_s"),  # shorter than one 8 Hz period
    (VIB, [8.0, 0.05, 5.0, 0.25, 0.0], "stable_g"),
    (VIB, [8.0, 0.05, 1e3, 0.25, 0.2], "max_duration_s"),
    (VIB, [8.0, 5.0, 5.0, 0.25, 0.2], "amplitude_rad"),
    ("TILT_UNTIL_LOAD", [0.2, 1.0, 1.0, -1.0, 0.2], "target_load_g"),
    ("TILT_UNTIL_LOAD", [0.0, 1.0, 1.0, 3.0, 0.2], "step_rad"),
    ("TILT_UNTIL_LOAD", [0.2, 1.0, 1e3, 3.0, 0.2], "velocity_rad_s"),
    ("TILT_UNTIL_LOAD", [0.2, 1.0, 1.0, 3.0, 0.001], "window_s"),
    ("TILT_UNTIL_LOAD", [0.2, 1.0, 1.0, 3.0], "5 parameter"),
])
def test_bad_parameters_are_refused_naming_the_field_and_nothing_moves(name, params, field):
    sim, rt = make()
    q = sim.q.copy()
    ok, msg = rt.start_primitive(name, params)
    assert not ok and field in msg
    for _ in range(25):
        sim.step(DT)
        rt.tick(sim.time, DT)
    assert rt.state().mode is Mode.DISABLED
    assert np.allclose(sim.q, q, atol=1e-3)


def test_a_tool_without_an_ft_sensor_refuses_closed_loop_primitives():
    sim, rt = make(ft=False)
    ok, msg = rt.start_primitive(VIB, [8.0, 0.05, 2.0, 0.25, 0.2])
    assert not ok and "F/T" in msg
    ok, _ = rt.start_primitive("VIBRATE_ROLL", [8.0, 0.05, 0.5])  # open loop still runs
    assert ok
    assert math.isfinite(float(sim.q[1]))
