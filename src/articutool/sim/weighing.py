"""Weighing the utensil's load: the F/T sensor's tare and readings, and an experimenter's scale.

:class:`Weighing` (the world's ``weighing``) tares the simulated F/T sensor as a user would,
reads the mass on the utensil from its tared force, says when that reading weighs the load
(gravity seen from the sensor as at the tare), and reads what a scale under the utensil would
(the food's contact forces on it, no sensor noise).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.sim.ledger import FoodLedger
from articutool.sim.mj_drivers import MjFTDriver
from articutool.spec import Spec

__all__ = ["Weighing"]

_ZUP = np.array([0.0, 0.0, 1.0])


class Weighing:
    """The F/T tare and the mass readings of one world.

    Args:
        spec: the hardware spec (the F/T rate and tare, gravity).
        data: the world's MuJoCo data (the sensor site's orientation).
        ft: the world's F/T driver.
        ft_site: the F/T sensor's site id.
        ledger: the world's food ledger (the items on the utensil, their contact forces).
        strands: the food is strands (a strand may hang from the utensil onto a surface).
        run: advances the world by so many seconds.
        run_until: steps the world until a condition holds or a timeout (s); True if it held.
    """

    def __init__(self, spec: Spec, data: mujoco.MjData, ft: MjFTDriver, ft_site: int,
                 ledger: FoodLedger, strands: bool, run: Callable[[float], None],
                 run_until: Callable[[Callable[[], bool], float], bool]) -> None:
        self.spec, self.data, self.ft, self.ledger, self.strands = spec, data, ft, ledger, strands
        self._ft_site = ft_site
        self._run, self._run_until = run, run_until
        self._tare_R: NDArray[np.float64] | None = None  # the sensor's orientation at the tare

    def _sensor_R(self) -> NDArray[np.float64]:
        return self.data.site_xmat[self._ft_site].reshape(3, 3)

    def tare(self, settle_s: float = 0.0) -> None:
        """Tare the F/T sensor as a user would: after ``settle_s`` at rest, average its next
        ``spec.ft.tare_samples`` samples (the utensil should be empty and still)."""
        self._run(settle_s)
        self.ft.tare()
        self._run_until(lambda: not self.ft.tare_pending, 1.0)
        self.ft.history.clear()  # samples before the new offset are not comparable
        self._tare_R = self._sensor_R().copy()

    def comparable(self, tol_deg: float = 3.0) -> bool:
        """True when gravity, seen from the sensor, is within ``tol_deg`` of where it was at
        the last tare: only then does the tared force weigh the load (the utensil's own
        weight was removed in that orientation; a turn about the vertical does not matter).
        False before the first tare."""
        if self._tare_R is None:
            return False
        c = float((self._tare_R.T @ _ZUP) @ (self._sensor_R().T @ _ZUP))
        return math.degrees(math.acos(min(1.0, max(-1.0, c)))) <= tol_deg

    def ft_mass_g(self, window_s: float = 1.0) -> float:
        """Mass on the utensil (g) as the F/T sensor measures it: the mean tared force over
        the last ``window_s`` projected on gravity in the sensor frame (meaningful at rest)."""
        n = max(1, round(window_s * self.spec.ft.rate_hz))
        hist = list(self.ft.history)[-n:]
        if not hist:
            return math.nan
        f = np.mean([s.force for s in hist], axis=0)
        down = self._sensor_R().T @ np.array([0.0, 0.0, -1.0])  # gravity in the sensor frame
        # The sensor reads the reaction on the utensil: extra weight pulls along −down.
        return float(-f @ down / self.spec.imu.gravity * 1000.0)

    def carried_g(self) -> float:
        """What a scale under the utensil reads (g): the downward force the food's
        contacts put on the utensil, over g — a strand hanging from the fork onto a surface
        counts as much as the fork bears of it. The F/T sensor measures the same force plus
        the utensil's own weight and inertia; this reads it without the sensor's noise, tare
        or orientation limits; the mean over the last 0.5 s (meaningful at rest)."""
        return self.ledger.carried_force_z() / -self.spec.imu.gravity * 1000.0

    def utensil_mass_g(self) -> float:
        """The mass on the utensil as an experimenter weighing it would find (g): the items on
        it (the ledger's ``utensil`` mass), or for strands what the utensil bears of them
        (:meth:`carried_g`)."""
        return self.carried_g() if self.strands else self.ledger.masses_g()["utensil"]
