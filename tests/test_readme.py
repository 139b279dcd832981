"""The README is a short front door that cannot go stale, and the architecture page's module
map names every module of the package; every page either links to exists."""

from __future__ import annotations

import re
from pathlib import Path

from conftest import ROOT, SRC

README = ROOT / "README.md"
ARCHITECTURE = ROOT / "docs" / "architecture.md"


def _map() -> set[str]:
    """The modules the map lists, as paths under src/articutool (``tool/runtime.py``)."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    block = text.split("```\nsrc/articutool/\n", 1)[1].split("```", 1)[0]
    out, package = set(), ""
    for line in block.splitlines():
        m = re.match(r"^( {2}| {4})(\S+)", line)
        if not m:
            continue
        name = m.group(2)
        if len(m.group(1)) == 2:
            package = name if name.endswith("/") else ""
            if not name.endswith("/"):
                out.add(name)
        else:
            out.add(package + name)
    return out


def test_the_architecture_map_lists_every_module() -> None:
    pkg = SRC / "articutool"
    modules = {str(p.relative_to(pkg)) for p in pkg.rglob("*.py")
               if p.name not in ("__init__.py", "__main__.py")}
    listed = _map()
    assert sorted(modules - listed) == [], "modules missing from docs/architecture.md's map"
    assert sorted(listed - modules) == [], "the map names modules that do not exist"


def _links(page: Path) -> list[Path]:
    text = page.read_text(encoding="utf-8")
    return [page.parent / t for t in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
            if "://" not in t]


def test_every_linked_page_exists() -> None:
    for page in (README, ARCHITECTURE, *sorted((ROOT / "docs").glob("*.md"))):
        for target in _links(page):
            assert target.exists(), f"{page.name} links to {target}"


def test_the_readme_is_a_short_front_door() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    # nothing that goes stale with every commit: no test counts or suite times
    assert not re.search(r"\d[\d ]* (passed|deselected)", text)
