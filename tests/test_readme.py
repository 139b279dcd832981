"""The README is a true front door: its architecture map names every module of the package, and
every page it links to exists."""

from __future__ import annotations

import re

from conftest import ROOT, SRC

README = (ROOT / "README.md").read_text(encoding="utf-8")


def _map() -> set[str]:
    """The modules the map lists, as paths under src/articutool (``tool/runtime.py``)."""
    block = README.split("```\nsrc/articutool/\n", 1)[1].split("```", 1)[0]
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
    assert sorted(modules - listed) == [], "modules missing from the README's map"
    assert sorted(listed - modules) == [], "the README's map names modules that do not exist"


def test_every_linked_page_exists() -> None:
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README):
        if "://" not in target:
            assert (ROOT / target).exists(), target
