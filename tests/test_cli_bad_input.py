"""Bad input and data safety: nonsense given to any command exits 2 with a message
naming the field and its allowed range, never a traceback, a hang or a lost file.

Every case runs the real command in a subprocess on this tree's sources.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path

import numpy as np
import pytest

from articutool.bench.runner import read_log
from articutool.link.config import ConfigError, LinkConfig
from conftest import assert_refused, free_port, minimal_env, run_cli

SRC = Path(__file__).parents[1] / "src"
EXAMPLE = Path(__file__).parents[1] / "examples" / "transport_feasible.json"
DEPTH = 100_000


_cli = functools.partial(run_cli, env=minimal_env())


# ----------------------------------------------------------- deep, odd files --
@pytest.fixture(scope="module")
def deep(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("deep")
    (d / "deep.json").write_text("[" * DEPTH + "]" * DEPTH)
    (d / "deep.toml").write_text("a = " + "[" * DEPTH + "]" * DEPTH)
    return {"json": d / "deep.json", "toml": d / "deep.toml"}


@pytest.mark.parametrize("command", [
    ("info", "--spec", "{json}"), ("info", "--spec", "{toml}"), ("verify", "{json}"),
    ("bench", "transport", "--tasks", "{json}", "--workers", "1", "--out", "{tmp}/o"),
    ("view", "--plan", "{json}", "--duration", "1", "--port", "{port}"),
])
def test_a_100000_deep_document_is_refused_naming_the_file(command, deep, tmp_path):
    args = [a.format(json=deep["json"], toml=deep["toml"], tmp=tmp_path, port=free_port())
            for a in command]
    path = next(a for a in args if a.startswith(str(deep["json"].parent)))
    assert_refused(_cli(*args), path, "nested too deeply")


def test_a_run_json_100000_deep_in_the_results_folder_is_refused(deep, tmp_path):
    (tmp_path / "run.json").write_text(deep["json"].read_text())
    assert_refused(_cli("bench", "transport", "--out", str(tmp_path), "--workers", "1", "--limit",
                  "1"), "run.json", "use another --out")
    (tmp_path / "capacity").mkdir()
    (tmp_path / "capacity" / "run.json").write_text(deep["json"].read_text())
    assert_refused(_cli("experiment", "capacity", "--trials", "1", "--workers", "1", "--out",
                  str(tmp_path)), "run.json", "use another --out")


def test_a_recording_whose_meta_is_100000_deep_is_refused(deep, tmp_path):
    from articutool.sim.recording import _ARRAYS

    rec = tmp_path / "deep.npz"
    np.savez(rec, meta=np.array(deep["json"].read_text()), mjcf=np.array(""),
             **{k: np.zeros(1) for k in _ARRAYS})
    assert_refused(_cli("view", "--recording", str(rec), "--export", str(tmp_path / "v.mp4")),
                   "--recording", "meta", "nested too deeply")


@pytest.mark.parametrize("kind", ["fifo", "/dev/zero", "folder"])
def test_info_spec_reads_regular_files_only_and_does_not_hang(kind, tmp_path):
    if kind == "fifo":
        path = tmp_path / "spec.toml"
        os.mkfifo(path)  # nobody ever writes: reading it would wait forever
    elif kind == "folder":
        path = tmp_path
    else:
        path = Path(kind)  # never ends: reading it would fill memory
    assert_refused(_cli("info", "--spec", str(path), timeout=60), str(path), "regular file")


# --------------------------------------------------------------- outputs --
@pytest.mark.parametrize("where", ["under_a_file", "proc"])
def test_an_out_folder_that_cannot_be_created_is_refused(where, tmp_path):
    (tmp_path / "afile").write_text("x")
    out = tmp_path / "afile" / "o" if where == "under_a_file" else Path("/proc/articutool-o")
    assert_refused(_cli("bench", "transport", "--out", str(out), "--workers", "1", "--limit", "1"),
                   "--out", str(out))
    assert_refused(_cli("experiment", "capacity", "--trials", "1", "--workers", "1", "--out",
                  str(out)), "--out", str(out))
    assert (tmp_path / "afile").read_text() == "x" and not out.exists()


def test_a_results_log_that_is_a_folder_is_refused(tmp_path):
    (tmp_path / "results.jsonl").mkdir()
    assert_refused(_cli("bench", "transport", "--out", str(tmp_path), "--workers", "1", "--limit",
                  "1"), "--out", "results.jsonl")
    (tmp_path / "capacity" / "trials.jsonl").mkdir(parents=True)
    assert_refused(_cli("experiment", "capacity", "--trials", "1", "--workers", "1", "--out",
                  str(tmp_path)), "--out", "trials.jsonl")


def test_output_files_in_proc_are_refused_before_any_work():
    assert_refused(_cli("bench", "tasks", "--count", "2", "--seed", "0", "--out",
                  "/proc/articutool-tasks.json"), "--out", "/proc/articutool-tasks.json")
    assert_refused(_cli("demo", "--plot", "/proc/articutool-demo.png"), "--plot",
                   "/proc/articutool-demo.png")


@pytest.mark.parametrize("command", [("info",), ("info", "--json"), ("verify", str(EXAMPLE))])
def test_an_unwritable_stdout_exits_2_without_a_traceback(command):
    with open("/dev/full", "w") as full:
        proc = _cli(*command, stdout=full.fileno())
    assert_refused(proc, "cannot write to standard output", "No space left on device")


def test_a_resume_log_line_that_is_json_but_not_an_object_is_ignored(tmp_path):
    rec = {"system": "decoupled", "task_id": 3, "seed": 0, "success": True}
    log = tmp_path / "results.jsonl"
    log.write_text("\n".join(["[1,2,3]", "42", "null", '"text"', json.dumps(rec),
                              "[" * 5000 + "]" * 5000]) + "\n")
    state = read_log(log)
    assert state.records == [rec] and state.corrupt == 5 and state.torn == 0


# ------------------------------------------------------- never overwrite --
def test_demo_plot_refuses_an_existing_file(tmp_path):
    plot = tmp_path / "mine.png"
    plot.write_bytes(b"my figure")
    r = _cli("demo", "--plot", str(plot), "--json")
    assert_refused(r, "--plot", str(plot), "refusing to overwrite")
    assert r.stdout == "" and plot.read_bytes() == b"my figure"


def test_demo_plot_in_a_folder_takes_the_next_free_name(tmp_path):
    from articutool.sim.demo import _plot_path

    (tmp_path / "demo_transport.png").write_bytes(b"old")
    (tmp_path / "demo_transport-2.png").write_bytes(b"older")
    assert _plot_path(str(tmp_path), default=False) == tmp_path / "demo_transport-3.png"
    assert not (tmp_path / "demo_transport-3.png").exists()  # checked, not yet written
    assert (tmp_path / "demo_transport.png").read_bytes() == b"old"


def test_an_edited_experiment_report_is_kept_before_regenerating(tmp_path):
    from articutool.experiments import report
    from articutool.experiments.config import ExperimentsConfig

    cfg = ExperimentsConfig.load()
    kept: list[tuple[Path, Path]] = []

    def write() -> Path:
        md, _ = report.write_report(tmp_path, cfg, on_kept=lambda p, c: kept.append((p, c)))
        return md

    md = write()
    write()  # unchanged since written: replaced, nothing kept
    assert kept == []
    edited = md.read_text() + "\nMy notes on the run.\n"
    md.write_text(edited)
    write()
    assert [p for p, _ in kept] == [md]
    assert kept[0][1].read_text() == edited and "My notes" not in md.read_text()
    # The CLI says so.
    md.write_text(edited)
    r = _cli("experiment", "report", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert "report.md was not as" in r.stderr and "kept it as" in r.stderr


# --------------------------------------------------------------- pairing --
@pytest.mark.parametrize("args,field", [
    (("--tool", "ca", "--pc", "pc-1"), "--tool must not be 'ca'"),
    (("--tool", "wrist-1", "--pc", "ca"), "--pc[0] must not be 'ca'"),
    (("--tool", "wrist-1", "--pc", "pc-1", "--pc", "CA"), "--pc[1] must not be 'ca'"),
    (("--tool", "wrist-1", "--pc", "pc-1", "--tool-host", "pi:7447"), "--tool-host must be"),
    (("--tool", "wrist-1", "--pc", "pc-1", "--tool-host", "[zz]"), "--tool-host must be"),
    (("--tool", "wrist-1", "--pc", "pc-1", "--tool-host", "a..b"), "--tool-host must be"),
    (("--tool", "wrist-1", "--pc", "pc-1", "--tool-host", "x" * 64), "--tool-host must be"),
])
def test_pair_refuses_bad_names_and_hosts_leaving_nothing(args, field, tmp_path):
    d = tmp_path / "pairing"
    assert_refused(_cli("pair", "--dir", str(d), *args), field)
    assert not d.exists()


def test_pair_writes_an_ipv6_tool_host_as_a_valid_endpoint(tmp_path):
    from articutool.link.config import load_config

    d = tmp_path / "pairing"
    assert _cli("pair", "--dir", str(d), "--tool", "w", "--pc", "p", "--tool-host",
                "fe80::1").returncode == 0
    assert load_config(d / "p" / "link.toml").connect == ("tls/[fe80::1]:7447",)


def test_pair_refuses_a_pc_as_the_tool_and_changes_nothing(tmp_path):
    d = tmp_path / "pairing"
    assert _cli("pair", "--dir", str(d), "--tool", "wrist-1", "--pc", "pc-1").returncode == 0
    before = {p: p.read_bytes() for p in d.rglob("*") if p.is_file()}
    assert_refused(_cli("pair", "--dir", str(d), "--tool", "pc-1", "--pc", "pc-2"), "--tool pc-1",
                   "not a tool's certificate")
    assert {p: p.read_bytes() for p in d.rglob("*") if p.is_file()} == before
    assert not (d / "pc-2").exists()


def test_a_pairing_that_fails_midway_leaves_nothing_behind(tmp_path):
    d = tmp_path / "pairing"
    d.mkdir()
    (d / "pc-1").write_text("in the way")  # the PC's folder cannot be made: after CA and tool
    r = _cli("pair", "--dir", str(d), "--tool", "wrist-1", "--pc", "pc-1")
    assert_refused(r, "nothing was kept")
    assert sorted(p.name for p in d.iterdir()) == ["pc-1"]
    assert (d / "pc-1").read_text() == "in the way"


# ------------------------------------------------------------ bounds, ranges --
def test_bench_tasks_count_is_bounded(tmp_path):
    out = tmp_path / "t.json"
    assert_refused(_cli("bench", "tasks", "--count", "1000000000", "--seed", "0", "--out", str(out),
                  timeout=60), "--count", "[1, 10000]")
    assert not out.exists()


@pytest.mark.parametrize("tols", [",", "nan", "0", "90", "5,abc"])
def test_bench_tolerances_must_be_degrees_in_range(tols, tmp_path):
    assert_refused(_cli("bench", "transport", "--tolerance-sweep", "--tolerances", tols, "--out",
                  str(tmp_path / "o"), "--workers", "1", "--limit", "1"),
                   "--tolerances", "(0, 90)")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args,words", [
    (("--at", "-5"), ("--at", "[0, 604800]")),
    (("--fps", "-1"), ("--fps", "--export")),
    (("--fps", "nan"), ("--fps", "--export")),
    (("--camera", "nowhere"), ("--camera", "--export")),
    (("--recording", "r.npz", "--export", "v.mp4", "--fps", "nan"), ("--fps", "(0, 120]")),
    (("--recording", "r.npz", "--export", "v.mp4", "--fps", "-1"), ("--fps", "(0, 120]")),
    (("--recording", "r.npz", "--export", "v.mp4", "--camera", "nowhere"),
     ("--camera", "overview")),
])
def test_view_nonsense_is_refused_before_serving(args, words, tmp_path):
    r = _cli("view", "--duration", "1", "--port", str(free_port()), *args, cwd=tmp_path)
    assert_refused(r, *words)
    assert "viewer: http" not in r.stdout


def test_report_thresholds_for_an_unknown_food_are_refused(tmp_path):
    r = _cli("experiment", "report", "--out", str(tmp_path), "--thresholds-g", "pizza=3")
    assert_refused(r, "--thresholds-g", "pecans", "water")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("ns", ["/*", "/**", "/articutool/*", "/a/$*", "//a", "/a/", "a"])
def test_a_wildcard_or_malformed_namespace_is_refused(ns, tmp_path):
    with pytest.raises(ConfigError, match="namespace must be"):
        LinkConfig(namespace=ns)
    cfg = tmp_path / "link.json"
    cfg.write_text(json.dumps({"namespace": ns}))
    assert_refused(_cli("client", "--link-config", str(cfg), "state", timeout=60), "namespace",
                   "'/articutool'")


def test_namespaces_in_use_still_load():
    for ns in ("/", "/articutool", "/lab_2/articutool"):
        assert LinkConfig(namespace=ns).namespace == ns


# ------------------------------------------------- a run's own result files --
RESULTS = Path(__file__).parents[1] / "results" / "experiments"
NAN_EXP1 = '{"acquired_g": {"noodles": {"articutool": {"mean": NaN}}, "pecans": {"articutool": ' \
           '{"mean": NaN}}, "water": {"articutool": {"mean": NaN}}}}'


def _plant(path: Path, kind: str) -> None:
    """A file that is not as articutool writes it, at ``path`` (its folder created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "garbage":
        path.write_text("this is not { json")
    elif kind == "shape":
        path.write_text('{"acquired_g": [1, 2], "foods": {"pecans": {"capacity_g": "heavy"}}}')
    elif kind == "deep":
        path.write_text("[" * DEPTH + "]" * DEPTH)
    elif kind == "binary":
        path.write_bytes(bytes(range(256)) * 8)
    elif kind == "folder":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)  # nobody writes: a read would wait forever
    elif kind == "nan":
        path.write_text(NAN_EXP1.replace('"articutool": {"mean": NaN}', '"articutool": '
                                         '{"mean": NaN}, "capacity_g": {"mean": NaN}')
                        .replace('"acquired_g"', '"foods": {"pecans": {"capacity_g": {"mean": '
                                 'NaN}}, "water": {"capacity_g": {"mean": NaN}}}, "acquired_g"'))
    elif kind == "dangling":
        path.symlink_to(path.parent / "nowhere.json")
    else:
        raise AssertionError(kind)


# What each command reads: meal, exp3 and the report read Exp. 1's summary (their
# thresholds), exp2c reads the capacity summary (its load).
_READERS = {
    "meal": (("meal", "--food", "pecans", "--bites", "1"), "exp1"),
    "report": (("experiment", "report", "--out", "{out}"), "exp1"),
    "exp3": (("experiment", "exp3", "--trials", "1", "--workers", "1", "--out", "{out}"),
             "exp1"),
    "exp2c": (("experiment", "exp2c", "--trials", "1", "--workers", "1", "--out", "{out}"),
              "capacity"),
}


@pytest.mark.parametrize("command,kind", [
    *(("report", k) for k in ("garbage", "shape", "deep", "binary", "folder", "fifo", "nan",
                               "dangling")),
    *((c, k) for c in ("meal", "exp3", "exp2c") for k in ("fifo", "nan")),
])
def test_a_result_summary_not_as_written_is_refused_naming_it(command, kind, tmp_path):
    args, exp = _READERS[command]
    out = tmp_path / "results" / "experiments"  # `meal` reads it relative to its folder
    summary = out / exp / "summary.json"
    _plant(summary, kind)
    r = _cli(*(a.format(out=out) for a in args), cwd=tmp_path, timeout=60)
    assert_refused(r, "summary.json")
    assert not (out / exp / "trials.jsonl").exists() and not (out / exp / "run.json").exists()
    assert not (out / "report.md").exists()


def test_an_unreadable_old_summary_is_refused_before_resuming(tmp_path):
    _plant(tmp_path / "capacity" / "summary.json", "garbage")
    r = _cli("experiment", "capacity", "--trials", "1", "--workers", "1", "--out",
             str(tmp_path))
    assert_refused(r, str(tmp_path / "capacity" / "summary.json"), "not valid JSON")
    assert sorted(p.name for p in (tmp_path / "capacity").iterdir()) == ["summary.json"]


@pytest.mark.parametrize("name", ["trials.jsonl", "summary.json", "run.json"])
def test_an_experiments_own_file_as_a_link_is_refused_and_the_target_kept(name, tmp_path):
    mine = tmp_path / "mine.txt"
    mine.write_text("my notes, no newline at the end")  # would be cut as a "torn tail"
    (tmp_path / "out" / "capacity").mkdir(parents=True)
    (tmp_path / "out" / "capacity" / name).symlink_to(mine)
    r = _cli("experiment", "capacity", "--trials", "1", "--workers", "1", "--out",
             str(tmp_path / "out"))
    assert_refused(r, "--out", name, "symbolic link")
    assert mine.read_text() == "my notes, no newline at the end"


def test_an_experiments_own_folder_as_a_link_is_refused(tmp_path):
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "capacity").symlink_to(tmp_path / "elsewhere")
    assert_refused(_cli("experiment", "capacity", "--trials", "1", "--workers", "1", "--out",
                  str(tmp_path / "out")), "--out", "capacity", "symbolic link")
    assert list((tmp_path / "elsewhere").iterdir()) == []


@pytest.mark.parametrize("name", ["results.jsonl", "results.csv", "cactus.png", "run.json"])
def test_a_benchmarks_own_file_as_a_link_is_refused_and_the_target_kept(name, tmp_path):
    mine = tmp_path / "mine.txt"
    mine.write_text('{"a torn": "tail"')
    out = tmp_path / "out"
    out.mkdir()
    (out / name).symlink_to(mine)
    r = _cli("bench", "transport", "--out", str(out), "--workers", "1", "--limit", "1",
             "--timeout", "1", "--systems", "decoupled")
    assert_refused(r, "--out", name, "symbolic link")
    assert mine.read_text() == '{"a torn": "tail"'
    assert not (out / "results.jsonl").exists() or name == "results.jsonl"


@pytest.fixture(scope="module")
def exp1_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the committed Exp. 1 results (log and summary): a report can be written."""
    out = tmp_path_factory.mktemp("results")
    (out / "exp1").mkdir()
    for name in ("trials.jsonl", "summary.json"):
        (out / "exp1" / name).write_bytes((RESULTS / "exp1" / name).read_bytes())
    return out


@pytest.mark.parametrize("name", ["exp1/exp1.png", "report.md", "report.html"])
def test_the_report_writes_no_figure_or_page_through_a_link(name, exp1_results, tmp_path):
    mine = tmp_path / "mine.png"
    mine.write_bytes(b"my own picture")
    link = exp1_results / name
    link.unlink(missing_ok=True)
    link.symlink_to(mine)
    try:
        assert_refused(_cli("experiment", "report", "--out", str(exp1_results)),
                       name.split("/")[-1], "symbolic link")
    finally:
        link.unlink()
    assert mine.read_bytes() == b"my own picture"


@pytest.mark.parametrize("name", ["report.md", "report.html", "exp1/notes.md"])
def test_a_report_page_or_notes_that_is_not_a_file_is_refused_before_any_figure(name, tmp_path):
    from articutool.datafile import ResultsError
    from articutool.experiments import report
    from articutool.experiments.config import ExperimentsConfig

    (tmp_path / "exp1").mkdir()
    for f in ("trials.jsonl", "summary.json"):
        (tmp_path / "exp1" / f).write_bytes((RESULTS / "exp1" / f).read_bytes())
    (tmp_path / name).mkdir()
    with pytest.raises(ResultsError, match=name.split("/")[-1]):
        report.write_report(tmp_path, ExperimentsConfig.load())
    assert sorted(p.name for p in (tmp_path / "exp1").iterdir()) == [
        "notes.md", "summary.json", "trials.jsonl"][name != "exp1/notes.md":]


def test_a_fifo_as_the_reports_notes_or_old_report_does_not_hang(exp1_results):
    for name in ("exp1/notes.md", "report.md"):
        (exp1_results / name).unlink(missing_ok=True)
        os.mkfifo(exp1_results / name)
        try:
            assert_refused(_cli("experiment", "report", "--out", str(exp1_results), timeout=60),
                     name.split("/")[-1])
        finally:
            (exp1_results / name).unlink()


# ------------------------------------------------------------------ numbers --
@pytest.mark.parametrize("step", ["1e-300", "1e-6"])
def test_a_step_too_small_to_check_is_refused_not_reported_feasible(step):
    r = _cli("verify", str(EXAMPLE), "--max-step-deg", step)
    assert_refused(r, "max_step_deg", "samples")
    assert "FEASIBLE" not in r.stdout


@pytest.mark.parametrize("command", [
    ("bench", "transport", "--out", "{tmp}/o", "--limit", "1"),
    ("experiment", "capacity", "--trials", "1", "--out", "{tmp}/o"),
])
@pytest.mark.parametrize("workers", ["100000000000000000000", "1025", "0", "1e20"])
def test_workers_must_be_a_count_in_range(command, workers, tmp_path):
    r = _cli(*(a.format(tmp=tmp_path) for a in command), "--workers", workers, timeout=60)
    assert_refused(r, "--workers", "[1, 1024]" if "e" not in workers else "invalid int value")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("loads", ["pecans=1e308,water=15", "pecans=7,water=inf",
                                   "pecans=nan,water=15", "pecans=101,water=15"])
def test_an_exp2c_load_beyond_any_utensil_is_refused(loads, tmp_path):
    assert_refused(_cli("experiment", "exp2c", "--trials", "1", "--workers", "1", "--out",
                  str(tmp_path), "--load-g", loads, timeout=60), "--load-g", "[0, 100]")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("setting,words", [
    ("extra = 5", ("extra must be a table",)),
    ('extra = {"a//b" = 1}', ("extra", "zenoh config path")),
    ('extra = {"transport/unicast/max_links" = nan}', ("extra", "finite")),
    ("reconnect_period = 1e308", ("reconnect_period", "(0, 60]")),
    ("heartbeat_period = 1e9", ("heartbeat_period", "(0, 10]")),
    ("call_timeout = inf", ("call_timeout", "(0, 3600]")),
    ('multicast_scouting = "yes"', ("multicast_scouting", "true or false")),
    ("publish_rate_hz = true", ("publish_rate_hz", "(0, 1000]")),
])
def test_link_config_values_out_of_range_are_refused_naming_the_field(setting, words,
                                                                       tmp_path):
    cfg = tmp_path / "link.toml"
    cfg.write_text(setting + "\n")
    assert_refused(_cli("client", "--link-config", str(cfg), "--wait", "1", "state", timeout=60),
             str(cfg), *words)


@pytest.mark.parametrize("var,value", [
    ("ROS_DOMAIN_ID", "abc"), ("ROS_DOMAIN_ID", "233"), ("ROS_DOMAIN_ID", "-1"),
    ("RMW_IMPLEMENTATION", "rmw_nothing_cpp"),
])
def test_a_bad_ros2_environment_is_refused_naming_the_variable(var, value):
    env = minimal_env(ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **{var: value})
    assert_refused(run_cli("ros2", "--wait", "1", env=env, timeout=60), var, repr(value))


def test_the_installed_middleware_is_accepted():
    from articutool.link.config import check_ros_environment, installed_rmw_implementations

    for rmw in installed_rmw_implementations():
        check_ros_environment({"RMW_IMPLEMENTATION": rmw, "ROS_DOMAIN_ID": "232"})
    check_ros_environment({"RMW_IMPLEMENTATION": "", "ROS_DOMAIN_ID": ""})  # rcl's defaults


@pytest.mark.parametrize("args", [
    ("vibrate_roll", *[str(k) for k in range(1100)]),  # 1 100 float32 parameters
    ("x" * 5000,),  # a name longer than any request the tool reads
])
def test_an_oversized_primitive_request_is_refused_before_sending(args):
    # Refused before waiting for a tool: told to wait an hour, it ends well before (the
    # timeout only bounds a failing test).
    r = _cli("client", "--wait", "3600", "primitive", *args, timeout=300)
    assert_refused(r, "max_request_bytes = 4096", "bytes")


def test_run_primitive_refuses_an_oversized_request_without_sending_it():
    from articutool.link.client import ArticutoolClient
    from articutool.link.memory_transport import MemoryBus, MemoryTransport

    class Spy(MemoryTransport):
        calls = 0

        def call(self, ep, payload, timeout):  # type: ignore[no-untyped-def]
            Spy.calls += 1
            return super().call(ep, payload, timeout)

    bus = MemoryBus()
    client = ArticutoolClient(LinkConfig(), Spy(bus))
    try:
        with pytest.raises(ValueError, match="max_request_bytes"):
            client.run_primitive("vibrate_roll", [1.0] * 1100)
        assert Spy.calls == 0
    finally:
        client.close()
        bus.close()


def test_meal_show_tree_needs_no_threshold_and_help_promises_no_yaml(tmp_path):
    r = _cli("meal", "--show-tree", cwd=tmp_path)  # no results/experiments here
    assert r.returncode == 0, r.stderr
    assert "bite tree for noodles" in r.stdout
    assert "YAML" not in _cli("meal", "--help").stdout
    (tmp_path / "s.yaml").write_text("strategies: {}\n")
    assert_refused(_cli("meal", "--strategies", str(tmp_path / "s.yaml"), "--show-tree"),
             "--strategies", "s.yaml", "YAML is not read")


# A careless user's inputs found by going over every subcommand once more.
@pytest.mark.parametrize("args,words", [
    (("verify", "{d}/garbage.json"), ("{d}/garbage.json", "joint_names")),
    (("view", "--recording", "{d}/fifo.npz", "--duration", "1"), ("fifo.npz", "FIFO")),
    (("view", "--recording", "{d}/dir.npz", "--duration", "1"), ("dir.npz", "folder")),
    (("bench", "transport", "--out", "{d}/dangling", "--workers", "1", "--limit", "1"),
     ("--out", "symbolic link to nothing")),
    (("experiment", "capacity", "--out", "{d}/dangling", "--workers", "1", "--trials", "1"),
     ("--out", "symbolic link to nothing")),
])
def test_careless_paths_are_refused_naming_the_file_and_what_it_is(args, words, tmp_path):
    (tmp_path / "garbage.json").write_text('{"a": 1}')
    os.mkfifo(tmp_path / "fifo.npz")
    (tmp_path / "dir.npz").mkdir()
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    r = _cli(*(a.format(d=tmp_path) for a in args), timeout=60)
    assert_refused(r, *(w.format(d=tmp_path) for w in words))
    assert not (tmp_path / "nowhere").exists()


# ------------------------------------------------------------- durations --
@pytest.mark.parametrize("args,option,allowed", [
    (("demo", "--timeout", "1e308"), "--timeout", "(0, 3600]"),
    (("demo", "--timeout", "nan"), "--timeout", "(0, 3600]"),
    (("demo", "--timeout=-inf"), "--timeout", "(0, 3600]"),
    (("demo", "--timeout", "0"), "--timeout", "(0, 3600]"),
    (("bench", "transport", "--timeout", "inf"), "--timeout", "(0, 3600]"),
    (("view", "--timeout", "3601"), "--timeout", "(0, 3600]"),
    (("view", "--duration", "1e308"), "--duration", "(0, 604800]"),
    (("view", "--at", "nan"), "--at", "[0, 604800]"),
    (("tool", "--duration=-1"), "--duration", "(0, 604800]"),
    (("client", "--wait", "1e308", "state"), "--wait", "(0, 3600]"),
    (("client", "--tool-timeout", "nan", "state"), "--tool-timeout", "(0, 3600]"),
    (("client", "primitive", "TWIRL", "--timeout", "1e300"), "--timeout", "(0, 3600]"),
    (("ros2", "--wait", "inf"), "--wait", "(0, 3600]"),
    (("ros2", "--tool-timeout", "1e308"), "--tool-timeout", "(0, 3600]"),
])
def test_an_absurd_duration_is_refused_naming_the_option_and_its_range(args, option,
                                                                      allowed):
    r = _cli(*args, timeout=60)
    value = next(a.partition("=")[2] or args[k + 1] for k, a in enumerate(args)
                 if a.partition("=")[0] == option)
    assert_refused(r, f"argument {option}", allowed, repr(value))
    assert r.stdout == ""  # refused before any work
