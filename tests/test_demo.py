"""`articutool demo`: plan, verify and execute one transport in simulation."""

import json

from articutool.cli import main
from articutool.sim.demo import run_demo
from articutool.spec import load_spec


def test_demo_figures_and_plot(tmp_path):
    plot = tmp_path / "demo.png"
    f = run_demo(load_spec(), seed=1, timeout_s=20.0, plot_path=plot)
    assert f["plan_success"] and f["feasible"], f
    assert 0 < f["velocity_margin"] <= 1
    assert f["max_tilt_error_deg"] < 5.0
    assert f["max_base_tilt_deg"] > 20  # a rigid spoon would have tilted this much
    assert f["sim_faults"] == []
    assert plot.stat().st_size > 10_000


def test_demo_cli_json(tmp_path, capsys):
    assert main(["demo", "--json", "--no-plot", "--seed", "2"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("plan_time_s", "feasible", "velocity_margin", "max_tilt_error_deg"):
        assert key in out
    assert main(["demo", "--timeout", "0"]) == 2
    assert "--timeout" in capsys.readouterr().err
    assert main(["demo", "--utensil", "knife"]) == 2
