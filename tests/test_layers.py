"""The import graph of ``src/articutool``: no import circles and no upward arrows. The layer
order is declared once (``LAYERS``) and every module belongs to one layer; imports go only
down, never up and never sideways to another package of the same layer unless the pair is
declared in ``SIBLINGS`` with its reason. Parsed with ``ast`` (lazy imports inside functions
count too)."""

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
# The layers, bottom first: a top-level module or package of ``articutool`` (its first name
# after ``articutool.``; "" is the package itself) imports only from lower layers.
LAYERS: tuple[tuple[str, ...], ...] = (
    # spec and data: the hardware spec, data files, units, frames, trajectories, shared types
    ("", "spec", "datafile", "dynamixel_units", "rotations", "trajectory", "api_types",
     "thresholds", "cli_support"),
    # the tool's onboard software, the arm's model, the food as values and pure physics
    ("tool", "arm", "food"),
    # the PC–tool link, plan-then-verify, the planners
    ("link", "verify", "planning"),
    # the physics world, the feeding task, the ROS 2 node, the Exp. 2a benchmark
    ("sim", "feeding", "ros2", "bench"),
    # the meal: the feeding task run in the physics world
    ("meal",),
    # the experiments, the viewer, the command lines
    ("experiments", "viewer", "cli", "onboard", "onboard_link", "__main__"),
)
# Imports between packages of one layer that are allowed, each with its reason; any other
# arrow across a layer is refused (feeding, ros2 and bench never see sim, nor sim them).
SIBLINGS: dict[tuple[str, str], str] = {
    ("spec", "datafile"): "the spec is a validated data file",
    ("spec", "dynamixel_units"): "the spec checks the motor registers' units",
    ("trajectory", "datafile"): "a trajectory file is read as a data file",
    ("thresholds", "datafile"): "the thresholds are read from a results file",
    ("cli_support", "spec"): "every command line loads the spec it is given",
    ("cli_support", "datafile"): "command lines refuse bad files as the data files do",
    ("planning", "verify"): "plan-then-verify: the planner checks its own output",
    ("__main__", "cli"): "the entry point runs the top-level command line",
    ("onboard", "onboard_link"): "the onboard command line serves the link's process",
}


def package(mod: str) -> str:
    """``articutool.sim.world`` → ``sim``; the package itself → ``""``."""
    return mod.split(".")[1] if "." in mod else ""


def layer_of(pkg: str) -> int:
    for i, names in enumerate(LAYERS):
        if pkg in names:
            return i
    raise KeyError(f"articutool.{pkg} is in no layer of LAYERS")


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """Every arrow that goes up a layer, or across one without a declared reason."""
    bad = []
    for a, deps in sorted(graph.items()):
        for b in sorted(deps):
            pa, pb = package(a), package(b)
            if pa == pb:
                continue
            la, lb = layer_of(pa), layer_of(pb)
            if lb > la:
                bad.append(f"{a} -> {b}: up from layer {la} ({pa}) to {lb} ({pb})")
            elif lb == la and (pa, pb) not in SIBLINGS:
                bad.append(f"{a} -> {b}: across layer {la} ({pa} and {pb}), not a declared "
                           "sibling import")
    return bad


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


def undeclared(graph: dict[str, set[str]]) -> list[str]:
    """A message for each top-level module or package in no layer."""
    declared = {p for names in LAYERS for p in names}
    return [f"articutool.{p} is in no layer: add it to LAYERS in tests/test_layers.py (and "
            "the layers of docs/architecture.md)" for p in sorted({package(m) for m in graph})
            if p not in declared]


def test_every_module_is_in_a_declared_layer() -> None:
    declared = [p for names in LAYERS for p in names]
    assert len(set(declared)) == len(declared), "a package in two layers"
    assert undeclared(GRAPH) == []
    # a new top-level module fails with its name
    assert undeclared({"articutool.newthing.core": set()}) == [
        "articutool.newthing is in no layer: add it to LAYERS in tests/test_layers.py (and the "
        "layers of docs/architecture.md)"]


def test_imports_only_go_down_the_declared_layers() -> None:
    assert layer_violations(GRAPH) == []


def test_every_declared_sibling_import_exists() -> None:
    # a reason kept for an arrow that no longer exists is stale
    used = {(package(a), package(b)) for a, deps in GRAPH.items() for b in deps}
    assert sorted(set(SIBLINGS) - used) == []


def test_the_layer_check_sees_an_upward_and_a_sideways_arrow() -> None:
    # guards the check: the two arrows the verifier and the ROS 2 service once had
    planted = {"articutool.verify.cli": {"articutool.sim.params"},
               "articutool.ros2.verify_service": {"articutool.sim.params"},
               "articutool.sim.params": set()}
    bad = layer_violations(planted)
    assert len(bad) == 2 and "across layer 3 (ros2 and sim)" in bad[0]
    assert "up from layer 2 (verify) to 3 (sim)" in bad[1]


def test_the_planners_verifier_ros2_food_and_feeding_do_not_import_the_simulation() -> None:
    for src in ("verify", "planning", "ros2", "food", "feeding"):
        for dst in ("sim", "meal", "experiments"):
            assert imports_from(GRAPH, f"articutool.{src}", f"articutool.{dst}") == []


def test_validating_the_spec_or_a_link_config_imports_neither_the_motor_sdk_nor_numpy() -> None:
    # the Bus Watchdog check needs the register's units, not dynamixel_sdk; and a command
    # refusing a bad --spec, --utensil or endpoint answers before the numerics load
    script = ("import sys\nfrom articutool.spec import load_spec\n"
              "from articutool.link.config import LinkConfig\n"
              "load_spec()\nLinkConfig()\n"
              "print(sorted(m for m in sys.modules if m.startswith(('dynamixel', 'numpy'))))\n")
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
    assert ("articutool.arm.ik" in GRAPH["articutool.planning.pc_arm"]
            and "articutool.arm.ik" in GRAPH["articutool.sim.demo"])
    for mod in ("articutool.meal.bites", "articutool.meal.cli"):
        assert "articutool.sim.scenes" not in GRAPH[mod]
        assert "articutool.arm.scene" in GRAPH[mod]


def test_the_pcs_arm_is_below_the_simulation_and_the_world_is_one_driver() -> None:
    # planning, verification, the food check and the tip's paths need no simulator: a real
    # arm is another driver of articutool.planning.pc_arm.ArmDriver
    for mod in ("articutool.planning.pc_arm", "articutool.planning.tip_paths"):
        assert layer_of(package(mod)) < layer_of("sim")
    users = sorted(m for m, deps in GRAPH.items() if "articutool.planning.pc_arm" in deps
                   and package(m) == "sim")
    assert users == ["articutool.sim.arm_driver"]
