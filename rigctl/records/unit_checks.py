"""Scales no friction record has: the likely sign of a unit mistake in a record from another lab.

A record converted to the CSV format (SI units) with one column left in the lab's own unit reads
as a physically odd rig, and a fit then ends far off without saying why: time in milliseconds
makes a 1 kHz record a 1 Hz one, a stage position in micrometres a drive of metres per second, a
tangential force in kN a friction coefficient of 1e-4. The workbench cannot tell a mistake from an
unusual rig, so these are warnings in the dataset's notes (shown first by ``compare`` and
``diagnose``, in the JSON and the report), naming the column and the unit it may be in; the record
is still analysed. The bounds are wide: each lies a factor of five or more outside the scales
friction records have (sample rates of 100 Hz to 20 kHz, slow drives, friction coefficients of
about 0.01 to 2, probes over micrometres to millimetres), while a unit slip moves a value by a
factor of a thousand or more, so an unusual rig is not flagged and a wrong unit is.
"""

from __future__ import annotations

import numpy as np

from rigctl.data import MeasuredRun
from rigctl.records.drive_profile import DriveProfile

MIN_RATE_HZ = 10.0
"""Below this sample rate no slip is resolved (stick-slip records: 100 Hz to 20 kHz)."""
MAX_RATE_HZ = 1e7
MAX_DRIVE_M_S = 5.0
"""Stick-slip needs a slow drive: a lab stage at 5 m/s (a stage position in um, or a time in
thousands of seconds) is a unit to check."""
MIN_DRIVE_M_S = 1e-10
FRICTION_RANGE = (2e-3, 20.0)
"""|Ft|/Fn (90th percentile under load, stage sliding) outside this: forces in different units
(N and kN)."""
MAX_DELTA_SPAN_M = 0.05
"""Displacement probes read micrometres to millimetres: a span of 5 cm is a unit to check."""
UNIT_NOTE = "check the units"
"""Every note of this module starts with it."""


def unit_notes(run: MeasuredRun, drive: DriveProfile, name: str,
               delta_measured: bool) -> list[str]:
    """Warnings for scales that suggest a column in another unit than the format's SI one."""
    notes: list[str] = []
    rate = run.sample_rate_hz
    if np.isfinite(rate) and rate < MIN_RATE_HZ:
        notes.append(f"{UNIT_NOTE} of {name}: t_s steps by {1.0 / rate:.3g} s ({rate:.3g} Hz), "
                     "too slow for a friction record: is t_s in seconds (not ms)?")
    elif np.isfinite(rate) and rate > MAX_RATE_HZ:
        notes.append(f"{UNIT_NOTE} of {name}: t_s steps by {1.0 / rate:.3g} s "
                     f"({rate:.3g} Hz): is t_s in seconds (not minutes or hours)?")
    v = np.abs(drive.moving_velocities)
    if v.size:
        v_typ = float(np.median(v))
        if v_typ > MAX_DRIVE_M_S:
            notes.append(f"{UNIT_NOTE} of {name}: the stage moves at {v_typ:.3g} m/s: is x_stage_m "
                         "in metres (not um or mm) and t_s in seconds?")
        elif 0.0 < v_typ < MIN_DRIVE_M_S:
            notes.append(f"{UNIT_NOTE} of {name}: the stage moves at {v_typ:.3g} m/s: is x_stage_m "
                         "in metres (not km) and t_s in seconds (not ms)?")
    ratio = _friction_ratio(run, drive)
    lo, hi = FRICTION_RANGE
    if ratio is not None and not lo <= ratio <= hi:
        only = "only " if ratio < lo else ""
        notes.append(f"{UNIT_NOTE} of {name}: |ft_N| / fn_N reaches {only}{ratio:.3g} under load; "
                     "friction coefficients are about 0.01 to 2: are both forces in newtons "
                     "(not one in kN or mN)?")
    if delta_measured:
        span = float(np.percentile(run.delta_m, 99.5) - np.percentile(run.delta_m, 0.5))
        if span > MAX_DELTA_SPAN_M:
            notes.append(f"{UNIT_NOTE} of {name}: d1_m - d2_m spans {span:.3g} m: are the probe "
                         "readings in metres (not um or mm)?")
    return notes


def _friction_ratio(run: MeasuredRun, drive: DriveProfile) -> float | None:
    """The 90th percentile of |Ft|/|Fn| where the contact is loaded (|Fn| above half its 99th
    percentile) and the stage slides; None where no normal force is recorded. Loaded rests are left
    out: a long rest before a short slide (Ft near 0 through most of the record) is not a force in
    kN."""
    fn = np.abs(run.fn_N)
    top = float(np.percentile(fn, 99.0)) if fn.size else 0.0
    if not top > 0.0:
        return None
    sliding = drive.sliding_velocity_at(run.t_s - drive.t0_s) != 0.0
    loaded = (fn > 0.5 * top) & sliding
    if np.count_nonzero(loaded) < 10:
        return None
    return float(np.percentile(np.abs(run.ft_N[loaded]) / fn[loaded], 90.0))
