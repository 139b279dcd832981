"""The twirl's turn budget, pure arithmetic on the spec: what ``sim --twirl-turns`` checks
before anything heavy is imported, and what the fork's acquisition
(:func:`articutool.sim.scenes.skewer`) turns by default."""

from __future__ import annotations

from articutool.spec import Spec

__all__ = ["max_twirl_turns"]


def max_twirl_turns(spec: Spec) -> float:
    """Turns a twirl may make from a roll near zero: the cable budget
    (``spec.wrist.roll_turn_budget``) less 0.1 turn for the roll a leveling leaves."""
    return spec.wrist.roll_turn_budget - 0.1
