"""docs/extending.md's examples run: every Python block of the page, each in a fresh namespace,
so the page's files-to-touch and examples stay true to the code."""

from __future__ import annotations

import re

import pytest

from conftest import ROOT

PAGE = ROOT / "docs" / "extending.md"


def _examples() -> list[tuple[str, str]]:
    """(section heading, code) of every ```python block of the page."""
    text = PAGE.read_text(encoding="utf-8")
    out, heading = [], "?"
    for block in re.split(r"(?m)^(## .+)$", text):
        if block.startswith("## "):
            heading = block[3:].strip()
            continue
        out += [(heading, code) for code in re.findall(r"```python\n(.*?)```", block, re.S)]
    return out


EXAMPLES = _examples()


def test_every_extension_point_has_an_example() -> None:
    assert [h for h, _ in EXAMPLES] == ["Add a food", "Add a utensil", "Add a primitive",
                                        "Add a strategy", "Add a planner", "Add an experiment"]


@pytest.mark.parametrize(("heading", "code"), EXAMPLES, ids=[h for h, _ in EXAMPLES])
def test_the_example_runs(heading: str, code: str) -> None:
    exec(compile(code, f"{PAGE.name}: {heading}", "exec"), {"__name__": "extending_example"})
