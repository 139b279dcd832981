"""The runtime's sensor reading: the IMU into the complementary filter, its freshness, and the
F/T sensor (thesis §3.2, §4.2).

Each tick :class:`Sensing` feeds every IMU sample since the last tick, in order, to the
filter. The IMU samples on its own timer at ``spec.imu.rate_hz`` and the stamps are reception
times (a batch read at once shares one), so the filter integrates the nominal period and only
a real gap in the stream (longer than four samples) re-initialises it. IMU data older than
``STALE_IMU_PERIODS`` loop periods is stale (a fault only while LEVELING: the runtime decides).
The F/T sensor is read for telemetry and the closed-loop primitives; a failing one never stops
the tool. A read that raises is counted, never propagated.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numpy.typing import NDArray

from articutool.spec import Spec
from articutool.tool.drivers.base import FTDriver, ImuDriver, ImuSample
from articutool.tool.filter import ComplementaryFilter

__all__ = ["STALE_IMU_PERIODS", "Sensing"]

log = logging.getLogger(__name__)

STALE_IMU_PERIODS = 2.0  # IMU data older than two loop periods is stale


class Sensing:
    """The latest IMU and F/T readings, their freshness and error counts."""

    def __init__(self, spec: Spec, imu: ImuDriver, ft: FTDriver | None,
                 filt: ComplementaryFilter) -> None:
        self.imu = imu
        self.ft = ft
        self.filter = filt
        self.stale_after = STALE_IMU_PERIODS * spec.wrist.period
        self._imu_dt = 1.0 / spec.imu.rate_hz
        self._imu_dt_max = 4.0 / spec.imu.rate_hz  # longer gaps re-initialise the filter
        self.last_imu: ImuSample | None = None
        self.last_imu_stamp = math.nan
        self.imu_fresh = False
        self.imu_bad = 0
        self.imu_resets = 0
        self.gyro_corrected = np.zeros(3)
        self.ft_last: tuple[float, ...] | None = None
        self.ft_fresh: NDArray[np.float64] | None = None  # this tick's force, for primitives
        self.ft_errors = 0

    def read_imu(self, now: float) -> None:
        """Feed the IMU's new samples to the filter; update freshness at ``now``."""
        try:
            samples = self.imu.read_all()
        except Exception as exc:  # staleness (and its fault while leveling) follows
            self.imu_bad += 1
            log.debug("IMU read failed: %s", exc)
            samples = []
        filt = self.filter
        dt_imu = self._imu_dt
        for s in samples:
            stamp = float(s.stamp)
            if filt.initialized and stamp - self.last_imu_stamp > self._imu_dt_max:
                self.imu_resets += 1
                filt.reset()
            try:
                filt.update(s.accel, s.gyro, dt_imu)
            except ValueError:
                self.imu_bad += 1
                continue
            self.last_imu = s
            self.last_imu_stamp = stamp
            self.gyro_corrected = np.asarray(s.gyro, dtype=np.float64) - filt.bias
        age = now - self.last_imu_stamp
        self.imu_fresh = bool(filt.initialized and age <= self.stale_after * (1 + 1e-9))

    def read_ft(self) -> None:
        """Read the F/T sensor, if any: ``ft_fresh`` is this tick's force or None."""
        self.ft_fresh = None
        if self.ft is None:
            return
        try:
            s = self.ft.read()
        except Exception:
            self.ft_errors += 1
            return
        if s is not None:
            self.ft_fresh = np.asarray(s.force, dtype=np.float64)
            self.ft_last = (*np.asarray(s.force).tolist(), *np.asarray(s.torque).tolist())

    def stale_message(self, now: float) -> str:
        """The fault message for stale IMU data while leveling."""
        age = now - self.last_imu_stamp
        age_txt = (f"last sample {age * 1e3:.0f} ms ago" if math.isfinite(age)
                   else "no sample yet")
        return (f"IMU data stale while leveling ({age_txt}; limit "
                f"{self.stale_after * 1e3:.0f} ms = {STALE_IMU_PERIODS:g} loop periods)")
