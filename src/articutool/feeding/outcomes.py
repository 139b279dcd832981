"""Outcome of a bite: the thesis' Exp. 3 hierarchy (§5, "Outcome hierarchy"), pure.

In order of severity, the worst that happened decides:

1. ``user_spill`` (critical failure): any food on the user, the wheelchair or the floor;
2. ``table_spill`` (non-critical failure): any other spill — food on the table, or food that
   left the utensil in transport and landed in a container (the plate or the bowl) or is
   still falling — none on the user;
3. ``failed``: no spill, but the bite did not complete (the tree failed or was stopped);
4. ``meaningful_success``: completed, no spill, delivered mass **above** the threshold;
5. ``trivial_success``: completed, no spill, delivered mass at or below the threshold.

Food shed back into its container by a primitive, over the container and before the
transport, is no spill (thesis §5: "Spillage that was intentionally shed back into the bowl
... was not counted as a failure"); it never appears in ``spilled_g``. Food lost in transport
is a spill wherever it lands, a container included (:func:`articutool.sim.accounting.
transport_spill`). The thesis' Exp. 3 threshold is 3.0 g; Exp. 2c takes its thresholds from
Exp. 1's mean acquisition masses.

The masses it reads mean one thing in every experiment and bite record, defined once in
:mod:`articutool.sim.accounting`: spilled grams count each item once, at the worst place it
reached (``spilled_by_place``); delivered is on the utensil plus eaten (``delivered_g``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

__all__ = ["OUTCOMES", "SPILL_PLACES", "Outcome", "classify_bite"]

Outcome = Literal["meaningful_success", "trivial_success", "table_spill", "user_spill", "failed"]
OUTCOMES: tuple[Outcome, ...] = ("meaningful_success", "trivial_success", "table_spill",
                                 "user_spill", "failed")
# The accounting's spill places (articutool.sim.accounting): "critical" is user, chair, floor;
# "container" and "airborne" only for food lost in transport.
SPILL_PLACES = ("table", "critical", "container", "airborne")
# A spill is any food at all: one water particle is 0.42 g, one pecan piece 0.92 g; below this
# is float noise in the accounting's sums.
_ANY_G = 1e-9


def classify_bite(delivered_g: float, spilled_g: Mapping[str, float], threshold_g: float,
                  completed: bool = True) -> Outcome:
    """The outcome class of one bite (see module doc).

    ``spilled_g`` maps spill places (:data:`SPILL_PLACES`) to grams: ``"critical"`` is a
    user spill, any other a non-critical one. Raises ``ValueError`` for a negative mass or
    threshold, or an unknown place."""
    if threshold_g < 0 or delivered_g < 0 or any(v < 0 for v in spilled_g.values()):
        raise ValueError("masses and the threshold must be non-negative")
    unknown = sorted(set(spilled_g) - set(SPILL_PLACES))
    if unknown:
        raise ValueError(f"spilled_g: unknown places {unknown}; allowed: {list(SPILL_PLACES)}")
    if spilled_g.get("critical", 0.0) > _ANY_G:
        return "user_spill"
    if any(v > _ANY_G for v in spilled_g.values()):
        return "table_spill"
    if not completed:
        return "failed"
    return "meaningful_success" if delivered_g > threshold_g else "trivial_success"
