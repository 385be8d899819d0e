"""What reading a record takes from its sample times and its drive alone.

:func:`rigctl.records.features.extract_events` reads the sample interval (the median step of the
times), the drive's sliding velocity at every sample (slip detection) and the stage position at
every sample (the settled post-slip lines of a drive that changes velocity) from the record's
times and its simplified drive, whatever the signals. A model run of the workbench is sampled on
its run's times at every evaluation, so :mod:`rigctl.workbench.evaluate` keeps one
:class:`TimeBase` per run and hands it to every reading of that run: the same numbers, computed
once (a reading checks that the times are the ones it was made for, :meth:`TimeBase.fits`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rigctl.records.drive_profile import DriveProfile
from rigctl.records.events import moving_median
from rigctl.records.signals import FloatArray, median


@dataclass(frozen=True, eq=False)
class TimeBase:
    """A record's times relative to its first sample, and what is read from them and the drive."""

    t_s: FloatArray
    """Sample times less the first."""
    dt_s: float
    """Sample interval: the median step (1.0 for a record of one sample)."""
    drive: DriveProfile
    v_sliding_m_per_s: FloatArray
    """The drive's sliding velocity at every sample (:func:`sliding_velocity`)."""
    t_given_s: FloatArray
    """The times as given (absolute), which :meth:`fits` compares."""

    @cached_property
    def v_moving_m_per_s(self) -> float:
        """The drive's typical sliding speed (:func:`rigctl.records.events.moving_median`)."""
        return moving_median(self.v_sliding_m_per_s)

    @classmethod
    def of(cls, t_s: FloatArray, drive: DriveProfile) -> TimeBase:
        t = t_s - t_s[0]
        dt = median(np.diff(t)) if t.size > 1 else 1.0
        return cls(t, dt, drive, sliding_velocity(drive, t), t_s)

    @cached_property
    def x_drive_m(self) -> FloatArray:
        """Stage position (simplified drive) at every sample."""
        return self.drive.x_at(self.t_s)

    def fits(self, t_s: FloatArray, drive: DriveProfile) -> bool:
        """Whether these are the times (``t_s``, absolute) and the drive it was made for."""
        return (drive is self.drive and t_s.shape == self.t_given_s.shape
                and bool(np.array_equal(t_s, self.t_given_s)))


def sliding_velocity(drive: DriveProfile, t: FloatArray) -> FloatArray:
    """``drive.sliding_velocity_at(t)`` for increasing sample times ``t``: each protocol phase's
    velocity (0 in holds) repeated over its samples (a search per phase, not per sample)."""
    starts = drive.t_s[drive.phase_knots[:-1]]
    bounds = np.searchsorted(t, starts[1:], side="left")
    counts = np.diff(np.concatenate([[0], bounds, [t.shape[0]]]))
    per_phase = np.where(drive.phase_is_hold, 0.0, drive.phase_velocity)
    out: FloatArray = np.repeat(per_phase, counts)
    return out
