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
        md, _ = report.write_report(tmp_path, cfg, thresholds_g=None, thresholds_source="",
                                    threshold_g=None, on_kept=lambda p, c: kept.append((p, c)))
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
    (("--at", "-5"), ("--at", ">= 0")),
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
