"""The report's Markdown pieces, pure: numbers, p-values, mean ± SD, intervals, tables."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["ci95", "mass_rows", "mean_sd", "num", "p_value", "places", "table"]


def num(x: Any, nd: int = 2) -> str:
    """``x`` with ``nd`` decimals if a float ("–" for None)."""
    if x is None:
        return "–"
    if isinstance(x, float):
        return f"{x:.{nd}f}"
    return str(x)


def p_value(x: Any) -> str:
    """A p-value in two significant digits ("n/a" for None)."""
    if x is None:
        return "n/a"
    return f"{x:.2g}" if x >= 1e-3 else f"{x:.1e}"


def mean_sd(d: Mapping[str, Any] | None, nd: int = 2) -> str:
    """A summary statistic as "mean ± SD"."""
    if not d or d.get("mean") is None:
        return "–"
    s = f"{d['mean']:.{nd}f}"
    if d.get("sd") is not None:
        s += f" ± {d['sd']:.{nd}f}"
    return s


def ci95(d: Mapping[str, Any] | None, nd: int = 2) -> str:
    """A summary statistic's 95 % interval as "[low, high]"."""
    if not d or d.get("ci_low") is None:
        return "–"
    return f"[{d['ci_low']:.{nd}f}, {d['ci_high']:.{nd}f}]"


def table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def places(d: Mapping[str, Any] | None) -> str:
    """``{"table": {"g", "trials"}, …}`` as "table 0.42 g (1), container …" (none: "none")."""
    parts = [f"{p} {v['g']:.2f} g ({v['trials']})" for p, v in (d or {}).items() if v["g"] > 0]
    return ", ".join(parts) or "none"


def mass_rows(block: Mapping[str, Any], foods: Sequence[str], systems: Sequence[str],
               thesis: Mapping[str, Any], cell: Any) -> list[list[Any]]:
    """Rows food | system | n | mean ± SD | 95 % CI | thesis cell | Welch p | thesis p (the
    p-values on each food's first row)."""
    rows = []
    for f in foods:
        e = block[f]
        for sys_ in systems:
            d, first = e[sys_], sys_ == systems[0]
            rows.append([f, sys_, d["n"], mean_sd(d), ci95(d), *cell(f, sys_, d),
                         p_value(e.get("welch", {}).get("p")) if first else "",
                         thesis.get(f, {}).get("p", "–") if first else ""])
    return rows

