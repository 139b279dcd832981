"""Benchmark reports: per-planner statistics, the table beside the thesis, CSV and plots.

:func:`summarize` is pure (records → numbers); the writers do the file I/O. Planning-time
statistics are over the *solved* trials (time to first solution, as in the thesis' cactus
plot, Fig. 6.2); the success rate is solved / trials. Plots use Matplotlib's Agg backend.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from articutool.datafile import replace_own, save_figure

__all__ = [
    "CSV_FIELDS",
    "THESIS",
    "cactus_plot",
    "render_table",
    "summarize",
    "summarize_sweep",
    "tolerance_sweep_plot",
    "write_results_csv",
    "write_sweep_csv",
]

# Thesis Exp. 2a (docs/hardware.md §7): RRT-Connect, 1000 s timeout, MoveIt + OMPL.
THESIS: dict[str, dict[str, float | None]] = {
    "decoupled": {"success_rate": 0.960, "median_time_s": 4.02, "mean_time_s": 4.7},
    "strict8": {"success_rate": 0.950, "median_time_s": 75.7, "mean_time_s": None},
    "strict6": {"success_rate": 0.860, "median_time_s": 31.0, "mean_time_s": None},
}

CSV_FIELDS = (
    "system", "task_id", "seed", "tolerance_deg", "planner", "timeout_s", "success",
    "planning_time_s", "attempts", "verification_rejections", "verified", "path_length",
    "max_tilt_deg", "duration_s", "message", "error",
)


def _stat(values: Sequence[float], fn: str) -> float | None:
    if not values:
        return None
    a = np.asarray(values, dtype=float)
    if fn == "median":
        return float(np.median(a))
    if fn == "mean":
        return float(np.mean(a))
    return float(np.percentile(a, 90))


def summarize(records: Iterable[dict[str, Any]], planners: Sequence[str]) -> dict[str, dict]:
    """Per-planner statistics of trial records (see :data:`CSV_FIELDS` for the fields).

    Keys per planner: ``trials``, ``successes``, ``success_rate``, ``median_time_s``,
    ``mean_time_s``, ``p90_time_s`` (solved trials), ``median_path_length``,
    ``median_max_tilt_deg``, ``mean_attempts``, ``verification_rejections`` (total),
    ``verified`` (trials whose final verification passed; None for strict planners),
    ``errors`` (planner exceptions), and the thesis' figures (``thesis_*``).
    """
    by: dict[str, list[dict[str, Any]]] = {s: [] for s in planners}
    for r in records:
        if r.get("system") in by:
            by[r["system"]].append(r)
    out: dict[str, dict] = {}
    for s, rs in by.items():
        ok = [r for r in rs if r.get("success")]
        times = [float(r["planning_time_s"]) for r in ok if r.get("planning_time_s") is not None]
        lengths = [float(r["path_length"]) for r in ok if r.get("path_length") is not None]
        tilts = [float(r["max_tilt_deg"]) for r in ok if r.get("max_tilt_deg") is not None]
        attempts = [int(r.get("attempts") or 0) for r in rs]
        verified = [r.get("verified") for r in rs if r.get("verified") is not None]
        th = THESIS.get(s, {})
        out[s] = {
            "trials": len(rs),
            "successes": len(ok),
            "success_rate": len(ok) / len(rs) if rs else None,
            "median_time_s": _stat(times, "median"),
            "mean_time_s": _stat(times, "mean"),
            "p90_time_s": _stat(times, "p90"),
            "median_path_length": _stat(lengths, "median"),
            "median_max_tilt_deg": _stat(tilts, "median"),
            "mean_attempts": float(np.mean(attempts)) if attempts else None,
            "verification_rejections": int(sum(int(r.get("verification_rejections") or 0)
                                               for r in rs)),
            "verified": sum(bool(v) for v in verified) if verified else None,
            "errors": sum(1 for r in rs if r.get("error")),
            "thesis_success_rate": th.get("success_rate"),
            "thesis_median_time_s": th.get("median_time_s"),
            "thesis_mean_time_s": th.get("mean_time_s"),
        }
    return out


def summarize_sweep(records: Iterable[dict[str, Any]], planner: str = "strict6",
                    ) -> dict[float, dict]:
    """Per-tolerance statistics (Fig. 5.1) of ``planner``'s records, sorted by tolerance."""
    by: dict[float, list[dict[str, Any]]] = {}
    for r in records:
        if r.get("system") == planner and r.get("tolerance_deg") is not None:
            by.setdefault(float(r["tolerance_deg"]), []).append(r)
    return {tol: summarize(by[tol], [planner])[planner] for tol in sorted(by)}


# ------------------------------------------------------------------- text --
def _fmt_time(x: float | None) -> str:
    if x is None:
        return "—"
    return f"{x * 1e3:.1f} ms" if x < 1.0 else f"{x:.2f} s"


def _fmt_rate(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f} %"


def render_table(summary: dict[str, dict], title: str = "Exp. 2a transport benchmark") -> Any:
    """A ``rich.table.Table`` of the summary beside the thesis' figures."""
    from rich.table import Table

    t = Table(title=title)
    for col in ("system", "solved", "success", "median", "mean", "p90", "path rad",
                "verification", "thesis: success / median / mean"):
        t.add_column(col, justify="left" if col in ("system", "verification") else "right")
    for s, v in summary.items():
        if v["verified"] is not None:
            ver = (f"{v['verified']} verified, {v['verification_rejections']} rejected, "
                   f"{v['mean_attempts']:.2f} attempts")
        elif v["median_max_tilt_deg"] is not None:
            ver = f"on path, median max tilt {v['median_max_tilt_deg']:.1f}°"
        else:
            ver = "—"
        if v["errors"]:
            ver += f"; {v['errors']} errors"
        path = v["median_path_length"]
        thesis = " / ".join((_fmt_rate(v["thesis_success_rate"]),
                             _fmt_time(v["thesis_median_time_s"]),
                             _fmt_time(v["thesis_mean_time_s"])))
        t.add_row(s, f"{v['successes']}/{v['trials']}", _fmt_rate(v["success_rate"]),
                  _fmt_time(v["median_time_s"]), _fmt_time(v["mean_time_s"]),
                  _fmt_time(v["p90_time_s"]), "—" if path is None else f"{path:.2f}", ver,
                  thesis)
    return t


# -------------------------------------------------------------------- CSV --
def _csv_value(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float) and not math.isfinite(v):
        return ""
    return v


def write_results_csv(records: Iterable[dict[str, Any]], path: str | Path) -> Path:
    """One row per trial, columns :data:`CSV_FIELDS`, sorted by planner, tolerance, task."""
    rows = sorted(records, key=lambda r: (str(r.get("system")), r.get("tolerance_deg") or 0.0,
                                          int(r.get("task_id", 0)), int(r.get("seed", 0))))
    f = io.StringIO(newline="")
    w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: _csv_value(r.get(k)) for k in CSV_FIELDS})
    return replace_own(path, f.getvalue())


def write_sweep_csv(sweep: dict[float, dict], path: str | Path) -> Path:
    """One row per tolerance: trials, successes, success rate, median/mean/p90 time."""
    cols = ("tolerance_deg", "trials", "successes", "success_rate", "median_time_s",
            "mean_time_s", "p90_time_s")
    f = io.StringIO(newline="")
    w = csv.writer(f)
    w.writerow(cols)
    for tol, v in sweep.items():
        w.writerow([tol, *(_csv_value(v[c]) for c in cols[1:])])
    return replace_own(path, f.getvalue())


# ------------------------------------------------------------------ plots --
_COLORS = {"decoupled": "tab:orange", "strict8": "dimgray", "strict6": "darkgray"}


def cactus_plot(records: Iterable[dict[str, Any]], planners: Sequence[str], path: str | Path,
                timeout_s: float | None = None) -> Path:
    """Fig. 6.2: solved problems sorted by planning time (x) vs. time (y, log), per planner."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    recs = list(records)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    drawn = 0
    for s in planners:
        rs = [r for r in recs if r.get("system") == s]
        t = sorted(float(r["planning_time_s"]) for r in rs
                   if r.get("success") and r.get("planning_time_s") is not None)
        if not rs:
            continue
        med = f", median {_fmt_time(float(np.median(t)))}" if t else ""
        label = f"{s} ({len(t)}/{len(rs)} solved{med})"
        ax.plot(np.arange(1, len(t) + 1), np.maximum(t, 1e-6), marker="o", markersize=3,
                color=_COLORS.get(s), label=label)
        drawn += 1
    if timeout_s is not None:
        ax.axhline(timeout_s, color="k", linestyle=":", linewidth=1,
                   label=f"timeout {timeout_s:g} s")
    ax.set_yscale("log")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("number of problems solved")
    ax.set_ylabel("planning time (s)")
    ax.set_title("Constrained transport: planning time profile (cf. thesis Fig. 6.2)")
    ax.grid(True, which="both", alpha=0.3)
    if drawn or timeout_s is not None:
        ax.legend(fontsize=8)
    fig.tight_layout()
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)


def tolerance_sweep_plot(sweep: dict[float, dict], path: str | Path,
                         planner: str = "strict6") -> Path:
    """Fig. 5.1: success rate and median planning time vs. orientation tolerance."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tols = list(sweep)
    rate = [100 * (sweep[t]["success_rate"] or 0.0) for t in tols]
    med = [sweep[t]["median_time_s"] if sweep[t]["median_time_s"] is not None else np.nan
           for t in tols]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(tols, rate, "o-", color="tab:blue", label="success rate")
    ax.set_xlabel("orientation tolerance ± (deg)")
    ax.set_ylabel("success rate (%)", color="tab:blue")
    ax.set_ylim(0, 105)
    ax2 = ax.twinx()
    ax2.plot(tols, med, "s--", color="tab:red", label="median planning time")
    ax2.set_yscale("log")
    ax2.set_ylabel("median planning time (s)", color="tab:red")
    ax.set_title(f"{planner}: success and time vs. tolerance (cf. thesis Fig. 5.1)")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)
