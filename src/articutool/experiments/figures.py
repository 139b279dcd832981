"""The figures that correspond to the thesis' (imperative shell: matplotlib, files).

- :func:`mass_bars` — mean with 95 % CI error bars per food and system, trials as dots
  (Exp. 1 cf. Fig. 6.1; Exp. 2b cf. Fig. 6.3);
- :func:`outcome_bars` — stacked bars of outcome classes with trial counts annotated
  (Exp. 2c cf. Fig. 6.4; Exp. 3 cf. Fig. 6.5).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from articutool.datafile import save_figure
from articutool.experiments.records import TrialRecord

__all__ = ["mass_bars", "outcome_bars"]

COLORS = {"articutool": "#e8772e", "baseline": "#8c8c8c"}
OUTCOME_COLORS = {"meaningful_success": "#2e8b57", "trivial_success": "#9acd32",
                  "transport_failure": "#d9534f", "table_spill": "#f0ad4e",
                  "user_spill": "#b22222", "failed": "#6c757d"}


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def mass_bars(records: Sequence[TrialRecord], summary: Mapping[str, Any],
              foods: Sequence[str], systems: Sequence[str], value: Callable[[Any], float],
              ylabel: str, title: str, path: str | Path) -> Path:
    """Bars of the mean of the outcomes' ``value`` per food and system with 95 % CI error
    bars, every trial a dot, Welch's p above each food."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(1.9 * len(foods) + 2.5, 4.2))
    width = 0.8 / len(systems)
    for j, s in enumerate(systems):
        x = np.arange(len(foods)) + (j - (len(systems) - 1) / 2) * width
        means, lo, hi = [], [], []
        for f in foods:
            d = summary.get(f, {}).get(s, {})
            m = d.get("mean")
            means.append(m if m is not None else 0.0)
            lo.append(m - d["ci_low"] if d.get("ci_low") is not None else 0.0)
            hi.append(d["ci_high"] - m if d.get("ci_high") is not None else 0.0)
        ax.bar(x, means, width, yerr=[lo, hi], capsize=4, label=s,
               color=COLORS.get(s), alpha=0.85)
        for xi, f in zip(x, foods, strict=True):
            v = [value(r.outcome) for r in records if r.condition.food == f
                 and r.condition.system == s and not r.error]
            jitter = np.linspace(-width / 4, width / 4, len(v)) if v else []
            ax.scatter(xi + np.asarray(jitter), v, s=10, color="k", zorder=3)
    top = ax.get_ylim()[1]
    ax.set_ylim(top=top * 1.12)  # room for the p-values above the highest trial
    for i, f in enumerate(foods):
        p = summary.get(f, {}).get("welch", {}).get("p")
        ax.text(i, top * 1.1, "Welch p = n/a" if p is None else f"Welch p = {p:.3g}",
                ha="center", va="top", fontsize=9)
    ax.set_xticks(np.arange(len(foods)), foods)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(frameon=False)
    fig.tight_layout()
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)


def outcome_bars(groups: Mapping[str, Mapping[str, int]], classes: Sequence[str], title: str,
                 path: str | Path) -> Path:
    """Stacked bars: one bar per group (label → counts per class), heights in percent of
    the group's trials, raw counts annotated."""
    plt = _plt()
    labels = list(groups)
    fig, ax = plt.subplots(figsize=(1.6 * len(labels) + 3.0, 4.2))
    bottom = np.zeros(len(labels))
    for c in classes:
        counts = np.array([groups[g].get(c, 0) for g in labels], dtype=float)
        n = np.array([max(1, sum(groups[g].values())) for g in labels], dtype=float)
        pct = 100.0 * counts / n
        if not counts.any():
            continue
        ax.bar(labels, pct, bottom=bottom, label=c.replace("_", " "),
               color=OUTCOME_COLORS.get(c))
        for i, (k, p) in enumerate(zip(counts, pct, strict=True)):
            if k:
                ax.text(i, bottom[i] + p / 2, f"{int(k)}", ha="center", va="center",
                        fontsize=9, color="white")
        bottom += pct
    ax.set_ylabel("trials (%)")
    ax.set_ylim(0, 100)
    ax.set_title(title, fontsize=10)
    ax.legend(frameon=False, fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    try:
        return save_figure(fig, path)
    finally:
        plt.close(fig)
