"""Which system takes the bite, as one value decided once and passed down.

The thesis compares two systems (§5): the **Articutool**, whose active wrist levels the
utensil (LEVELING) while the decoupled planner carries it under a loose constraint that the
verifier checks the wrist can follow (Alg. 2), and the rigid 6-DOF **baseline**, whose wrist
is locked (DISABLED at zero) while a strict planner keeps the utensil level with the arm.
:class:`System` is built from a strategy (:meth:`System.from_strategy`) or a system's name
(:meth:`System.of`) — the only place the names are read — and the feeding tree, the meal and
the experiments ask it what to do instead of comparing names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from articutool.tool.api import Mode

if TYPE_CHECKING:
    from articutool.feeding.strategies import Strategy

__all__ = ["DECOUPLED", "LOOSE", "SYSTEMS", "Planner", "System"]

SYSTEMS = ("articutool", "baseline")


@dataclass(frozen=True)
class Planner:
    """How the tree plans a move: the planner (one of
    :data:`articutool.planning.types.PLANNERS`, by its name, as the arm is asked for it),
    whether each plan is verified before it runs (plan-then-verify, Alg. 2), and a strict
    planner's tolerance band (None for the decoupled planner, whose band is the spec's)."""

    name: str
    verified: bool
    tolerance_deg: float | None = None


# The decoupled planner with verification: the Articutool's loaded moves.
DECOUPLED = Planner("decoupled", verified=True)
# The loose planner without verification: moves of the empty utensil, for both systems
# ("where spillage is not a concern", §4.3.1).
LOOSE = Planner("decoupled", verified=False)


@dataclass(frozen=True)
class System:
    """One system (see the module doc). ``wrist``: the active wrist levels the utensil (the
    Articutool); False: it is locked at zero (the rigid baseline). ``transport`` carries the
    loaded utensil (to Resting, to Staging); ``home`` moves it back to Resting after the bite
    or a failed one."""

    name: str
    wrist: bool
    transport: Planner
    home: Planner

    @property
    def carry(self) -> Mode:
        """The tool's mode while the utensil is carried: LEVELING with the active wrist,
        DISABLED (locked) without."""
        return Mode.LEVELING if self.wrist else Mode.DISABLED

    @classmethod
    def of(cls, name: str, planner: str | None = None,
           tolerance_deg: float | None = None) -> System:
        """The system ``name`` (one of :data:`SYSTEMS`) transporting with ``planner``
        (default: its own — decoupled for the Articutool, strict6 for the baseline);
        ``tolerance_deg`` is kept for a strict planner only (the decoupled planner's band is
        the spec's). Raises ``ValueError`` naming the field for a name it does not know or a
        baseline given the decoupled planner."""
        if name not in SYSTEMS:
            raise ValueError(f"system: unknown system {name!r}; known: {', '.join(SYSTEMS)}")
        wrist = name == "articutool"
        planner = planner or ("decoupled" if wrist else "strict6")
        if planner == DECOUPLED.name:
            if not wrist:
                raise ValueError("planner: a baseline cannot use the decoupled planner "
                                 "(no wrist)")
            transport = DECOUPLED
        else:
            transport = Planner(planner, verified=False, tolerance_deg=tolerance_deg)
        return cls(name, wrist, transport, DECOUPLED if wrist else transport)

    @classmethod
    def from_strategy(cls, strategy: Strategy) -> System:
        """The system a strategy takes its bite with (its ``system`` and its transport)."""
        t = strategy.transport
        return cls.of(strategy.system, t.planner, t.tolerance_deg)
