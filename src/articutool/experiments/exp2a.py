"""Exp. 2a (thesis §5.2.1, H2): the transport planning benchmark as the report reads it.
Its trials are ``articutool bench transport``'s (:mod:`articutool.bench`); this module reads
their records, summarises them, writes their section and judges their claims beside the
experiments' (:func:`articutool.experiments.report.verdicts`)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from articutool.experiments.analysis import compare_counts, pv
from articutool.experiments.markdown import table
from articutool.experiments.stats import bootstrap_ci, mann_whitney, welch, wilcoxon_paired
from articutool.experiments.verdicts import Verdict, judge

__all__ = ["BENCHMARK", "read_exp2a", "section_exp2a", "summarize_exp2a"]


class _BenchRun(BaseModel):
    model_config = ConfigDict(extra="allow", frozen=True)

    timeout_s: Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
    planner: str | None = None


def read_exp2a(directory: Path) -> tuple[dict[str, Any] | None, list[dict[str, Any]]]:
    """The transport benchmark's run settings (``run.json``) and records
    (``results.jsonl``, :func:`articutool.bench.runner.read_log`) in ``directory``;
    ``(None, [])`` when it holds none."""
    from articutool.bench.runner import read_log
    from articutool.datafile import read_own_json

    run = read_own_json(directory / "run.json", "Exp. 2a run settings", _BenchRun)
    if run is None:
        return None, []
    return run.model_dump(), read_log(directory / "results.jsonl").records



def summarize_exp2a(records: Sequence[Mapping[str, Any]], timeout_s: float,
                    decoupled: str = "decoupled") -> dict[str, Any]:
    """The transport planning benchmark (Exp. 2a, ``articutool bench transport``'s records),
    ``decoupled`` against each strict planner (a record's ``system``): tasks solved (Fisher,
    Boschloo; Newcombe's interval of the difference) and planning time. Times: the ratio of
    the strict planner's
    median to the decoupled one's over the solved tasks (the thesis' medians), with the
    bootstrap interval; Mann–Whitney, Welch and the Wilcoxon signed-rank test (tasks
    paired) over every task, a failed plan counted as taking the whole ``timeout_s``."""
    by: dict[str, dict[int, Mapping[str, Any]]] = {}
    for r in records:
        if r.get("tolerance_deg") is None:  # the benchmark's own ±10°, not a sweep
            by.setdefault(str(r["system"]), {})[int(r["task_id"])] = r

    def time(r: Mapping[str, Any]) -> float:
        return float(r["planning_time_s"]) if r.get("success") else float(timeout_s)

    def solved(rs: Iterable[Mapping[str, Any]]) -> list[float]:
        return [float(r["planning_time_s"]) for r in rs if r.get("success")]

    every = [t for rs in by.values() for t in solved(rs.values())]
    out: dict[str, Any] = {"timeout_s": timeout_s, "planners": {}, "against": {},
                           "max_solved_s": max(every) if every else None}
    for name, rs in by.items():
        t = solved(rs.values())
        out["planners"][name] = {"tasks": len(rs), "solved": len(t),
                                 "median_s": float(np.median(t)) if t else None}
    dec = by.get(decoupled, {})
    for name, rs in by.items():
        if name == decoupled or not dec:
            continue
        tasks = sorted(set(rs) & set(dec))
        a = [time(rs[k]) for k in tasks]
        d = [time(dec[k]) for k in tasks]
        sa, sd = solved(rs[k] for k in tasks), solved(dec[k] for k in tasks)
        times = {"n": [len(a), len(d)],
                 "p": {"mann_whitney": pv(mann_whitney(a, d)), "welch": pv(welch(a, d).p),
                       "wilcoxon": pv(wilcoxon_paired(a, d)) if tasks else None},
                 "effect": {"bootstrap": bootstrap_ci(sa, sd, "median ratio").to_dict()
                            if sa and sd else None}}
        out["against"][name] = {
            "tasks": len(tasks),
            "success": compare_counts(len(sd), len(tasks), len(sa), len(tasks)),
            "time": times}
    return out



def section_exp2a(s: Mapping[str, Any], run: Mapping[str, Any], cfg: Any, where: str) -> str:
    """The planning benchmark beside the thesis' Fig. 6.2 (our records at ``where``)."""
    th = cfg.thesis.get("exp2a", {})
    rows = []
    for name, v in s["planners"].items():
        t = th.get(name, {})
        med = v.get("median_s")
        rows.append([name, f"{v['solved']}/{v['tasks']}",
                     "–" if med is None else f"{med * 1e3:.1f} ms",
                     f"{t['success']:g} %, median {t['median_s']:g} s" if t else "–"])
    return ("## Exp. 2a — transport planning benchmark (H2, §5.2.1; cf. Fig. 6.2)\n\n"
            + table(["system", "solved", "median planning time (solved)",
                      f"thesis ({th.get('timeout_s', '?'):g} s timeout)"], rows)
            + f"\n\nOur records: `{where}` ({run.get('planner', '?')}, "
              f"{s['timeout_s']:g} s per task; `articutool bench transport --out {where}`; "
              "docs/planning.md). A failed plan counts as taking the whole timeout in the "
              "rank tests.\n")



def claims_exp2a(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float,
                 tests: Mapping[str, Any]) -> list[Verdict]:
    """The benchmark's claims (tasks solved, planning time) against the thesis' ``th``."""
    out = []
    dec = "decoupled"
    tdec = th.get(dec, {})
    sysd = s.get("planners", {})
    for base, v in s.get("against", {}).items():
        tb = th.get(base, {})
        ours_d, ours_b = sysd.get(dec, {}), sysd.get(base, {})
        comp = v["success"]
        k = comp.get("k", [0, 0])
        n = comp.get("n", [0, 0])
        at_bound = k[0] * n[1] == k[1] * n[0] and k[0] in (0, n[0])
        given = "success" in tdec and "success" in tb
        test, size, others, verdict = judge(
            comp, tests["exp2a_success"],
            (tdec["success"] - tb["success"]) / 100 if given else None, +1, alpha,
            at_bound or not n[0] or not n[1], "points")
        timeout = s.get("timeout_s")
        out.append(Verdict(
            "H2", "Fig. 6.2", f"transport planning: the decoupled planner solves more tasks "
            f"than {base} (±10°)",
            f"{tdec.get('success', '–')} % vs {tb.get('success', '–')} % solved "
            f"({th.get('timeout_s', '?'):g} s)" if given else "not given",
            f"{k[0]}/{n[0]} vs {k[1]}/{n[1]} solved ({timeout:g} s)" if timeout else
            f"{k[0]}/{n[0]} vs {k[1]}/{n[1]} solved", test, size, others, verdict))
        given = "median_s" in tdec and "median_s" in tb
        md, mb = ours_d.get("median_s"), ours_b.get("median_s")
        test, size, others, verdict = judge(
            v["time"], tests["exp2a_time"],
            tb["median_s"] / tdec["median_s"] if given else None, +1, alpha,
            md is None or mb is None, "×")
        out.append(Verdict(
            "H2", "Fig. 6.2", f"transport planning: the decoupled planner plans faster than "
            f"{base} ({base} / decoupled median)",
            f"median {tdec['median_s']:g} vs {tb['median_s']:g} s" if given else "not given",
            f"median {md * 1e3:.1f} vs {mb * 1e3:.1f} ms" if md is not None and mb is not None
            else "no solved task", test, size, others, verdict))
    return out



def facts(summary: Mapping[str, Any] | None) -> dict[str, str]:
    """The figures the deviations table quotes from the benchmark's summary."""
    f: dict[str, str] = {}
    a2 = summary
    if a2:
        f["exp2a_timeout_s"] = f"{a2['timeout_s']:g}"
        f["exp2a_algorithm"] = str(a2.get("algorithm", "?"))
        f["exp2a_tasks"] = str(max((v["tasks"] for v in a2["planners"].values()), default=0))
        if a2.get("max_solved_s") is not None:
            f["exp2a_max_solved_s"] = f"{a2['max_solved_s']:.1f}"
        f["exp2a_unsolved"] = ", ".join(
            f"{k} {v['tasks'] - v['solved']} of {v['tasks']}"
            for k, v in a2["planners"].items()) or "–"
    return f


class _Benchmark:
    """The benchmark's place among the claims (:func:`~articutool.experiments.report.
    verdicts`): between Exp. 1 and Exp. 2b, as the thesis orders them."""

    name = "exp2a"
    hypothesis = "H2"
    thesis_figure = "Fig. 6.2"
    order = 15
    unjudged = ""
    claims: ClassVar[dict[str, str]] = {"exp2a_success": "Exp. 2a tasks solved (H2)",
                                        "exp2a_time": "Exp. 2a planning time (H2)"}

    def verdicts(self, summary: Mapping[str, Any], thesis: Mapping[str, Any], alpha: float,
                 tests: Mapping[str, Any]) -> list[Verdict]:
        """The benchmark's claims."""
        return claims_exp2a(summary, thesis, alpha, tests)


BENCHMARK = _Benchmark()
