"""The import graph of ``src/articutool``: no import circles and no upward arrows. Imports go
down the README's layers: spec/data → tool, arm, food → link, verify, planning → sim,
feeding → meal → experiments, viewer, CLIs (the feeding task does not know the simulator;
``meal`` joins them). Parsed with ``ast`` (lazy imports inside functions count too)."""

import ast
import subprocess
import sys
from pathlib import Path

import articutool

ROOT = Path(articutool.__file__).parent


def import_graph() -> dict[str, set[str]]:
    """Module → the articutool modules it imports (anywhere in the file)."""
    mods: dict[str, Path] = {}
    for p in ROOT.rglob("*.py"):
        parts = list(p.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = p
    graph: dict[str, set[str]] = {}
    for mod, path in mods.items():
        pkg = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        out: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                out.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    name = ".".join(base + ([node.module] if node.module else []))
                else:
                    name = node.module or ""
                for a in node.names:
                    full = f"{name}.{a.name}"
                    out.add(full if full in mods else name)
        graph[mod] = {m for m in out if m in mods and m != mod}
    return graph


def circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(comp)

    for v in graph:
        if v not in index:
            visit(v)
    return found


def imports_from(graph: dict[str, set[str]], src: str, dst: str) -> list[tuple[str, str]]:
    """Arrows from modules under ``src`` to modules under ``dst`` (package prefixes)."""
    def under(m: str, p: str) -> bool:
        return m == p or m.startswith(p + ".")
    return sorted((a, b) for a, bs in graph.items() if under(a, src)
                  for b in bs if under(b, dst))


GRAPH = import_graph()
FIXED_CIRCLES = [
    {"articutool.spec", "articutool.tool.drivers.dynamixel"},
    {"articutool.planning.api", "articutool.planning.ompl_planner"},
    {"articutool.sim.world", "articutool.sim.mj_drivers"},
]
FIXED_ARROWS = [
    ("articutool.spec", "articutool.tool"),
    ("articutool.tool", "articutool.link"),
    ("articutool.feeding", "articutool.experiments"),
    ("articutool.sim", "articutool.viewer"),
    ("articutool.feeding", "articutool.viewer"),
    ("articutool.feeding", "articutool.sim"),
    ("articutool.feeding", "articutool.meal"),
    ("articutool.sim", "articutool.feeding"),
    ("articutool.sim", "articutool.meal"),
]


def test_the_graph_sees_imports() -> None:
    # guards the parser: a known downward import is found
    assert "articutool.spec" in GRAPH["articutool.tool.runtime"]


def test_no_fixed_circle_returns() -> None:
    for comp in circles(GRAPH):
        for fixed in FIXED_CIRCLES:
            assert len(comp & fixed) < 2, f"import circle again: {sorted(comp)}"


def test_the_import_graph_has_no_circle_at_all() -> None:
    # A new circle (sim.params ⇄ sim.pieces came back with the pecan pieces) fails here.
    assert circles(GRAPH) == []


def test_no_fixed_upward_arrow_returns() -> None:
    for src, dst in FIXED_ARROWS:
        assert imports_from(GRAPH, src, dst) == []


def test_validating_the_spec_does_not_import_the_motor_sdk() -> None:
    # the Bus Watchdog check needs the register's units, not dynamixel_sdk
    script = ("import sys\nfrom articutool.spec import load_spec\n"
              "load_spec()\n"
              "print(sorted(m for m in sys.modules if m.startswith('dynamixel')))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=120, check=True)
    assert out.stdout.strip() == "[]"


def test_the_mujoco_drivers_do_not_see_the_world() -> None:
    # the world owns its drivers; they read its state through a MotorPlant
    assert "articutool.sim.world" not in GRAPH["articutool.sim.mj_drivers"]


def test_only_the_entry_point_imports_the_top_level_cli() -> None:
    # the sub-CLIs share articutool.cli_support; articutool.cli gathers them at the top
    users = sorted(m for m, deps in GRAPH.items() if "articutool.cli" in deps)
    assert users == ["articutool.__main__"]


def test_feeding_takes_the_staging_goal_and_the_scoop_heading_from_the_arm_layer() -> None:
    # not from the demo or the scripted scenes (sim/demo.py, sim/scenes.py)
    assert imports_from(GRAPH, "articutool.feeding", "articutool.sim.demo") == []
    assert ("articutool.arm.ik" in GRAPH["articutool.meal.sim_arm"]
            and "articutool.arm.ik" in GRAPH["articutool.sim.demo"])
    for mod in ("articutool.meal.bites", "articutool.meal.cli"):
        assert "articutool.sim.scenes" not in GRAPH[mod]
        assert "articutool.arm.scene" in GRAPH[mod]
