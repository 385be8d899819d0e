"""The ``probe_recentre`` event: a probe's mount moved during a run, when, for how long, by how much.

Written by the protocols' re-centring (:mod:`experiments.recentre`) into the run file's event table
(docs/run-file.md), read by every reader of a run file to stitch delta across the move
(:mod:`rigctl.records.delta_stitch`). One format, declared here::

    <column>: mount moved <+-um> um at <t0> s in <duration> s (reading <+-um> -> <+-um> um)

e.g. ``d1_m: mount moved +35.0120 um at 81.2305 s in 0.0870 s (reading +5.4000 -> -29.6120 um)``.
A positive move brings the probe towards its target: the readings drop by it. ``t0`` (device time,
the recorded time axis) and ``duration`` bound the samples during which the mount was moving: before
``t0`` it had not started, after ``t0 + duration`` it had arrived. The move is ``nan`` when its size
is not known (an operator's re-centring), a reading ``nan`` when it was not known (over range).
A message without ``at ... in ...`` (older run files) states no window. :func:`moving_masks` gives
the samples recorded while a mount was moving (bridged by the stitching, and left out of delta
where the specimen was not steady across the move: :mod:`rigctl.records.delta_stitch`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

if TYPE_CHECKING:
    from rigctl.storage.reader import RunEvent

RECENTRE_EVENT = "probe_recentre"
"""Event name of a mount move."""
NOT_RECENTRED_EVENT = "probe_not_recentred"
"""Event name of a re-centring that could not be made (the reason in the message)."""

_NUMBER = r"[+-]?(?:[0-9.]+(?:e[+-]?[0-9]+)?|nan|inf)"
_MESSAGE = re.compile(rf"\s*(\w+):\s*mount moved\s+({_NUMBER})\s*um"
                      rf"(?:\s+at\s+({_NUMBER})\s*s\s+in\s+({_NUMBER})\s*s)?")


class MountMove(NamedTuple):
    """One recorded mount move (:func:`parse_recentre`)."""

    column: str
    """The recorded probe column (``d1_m``, ``d2_m``)."""
    moved_m: float
    """The move [m] (positive: towards the target, the readings drop by it); NaN if unknown."""
    t_start_s: float = math.nan
    """Device time the mount may have started moving [s]; NaN where the message states no window."""
    duration_s: float = math.nan
    """How long after ``t_start_s`` the mount may still have been moving [s]; NaN if not stated."""

    @property
    def has_window(self) -> bool:
        return math.isfinite(self.t_start_s) and math.isfinite(self.duration_s)


def recentre_message(
    column: str,
    moved_m: float,
    before_m: float,
    after_m: float,
    t_start_s: float = math.nan,
    duration_s: float = math.nan,
) -> str:
    """The event message of a mount move of ``moved_m`` on the probe recorded as ``column``, made
    within ``duration_s`` from device time ``t_start_s`` (left out of the message when not known)."""
    window = ""
    if math.isfinite(t_start_s) and math.isfinite(duration_s):
        window = f" at {t_start_s:.4f} s in {duration_s:.4f} s"
    return (f"{column}: mount moved {moved_m * 1e6:+.4f} um{window} (reading {before_m * 1e6:+.4f} "
            f"-> {after_m * 1e6:+.4f} um)")


def parse_recentre(message: str) -> MountMove | None:
    """The mount move a ``probe_recentre`` message states; None when it is not such a message."""
    m = _MESSAGE.match(message)
    if m is None:
        return None
    column, moved, t0, duration = m.groups()
    if t0 is None or duration is None:
        return MountMove(column, float(moved) * 1e-6)
    return MountMove(column, float(moved) * 1e-6, float(t0), float(duration))


def moving_masks(t_s: np.ndarray, events: Iterable[RunEvent]) -> dict[str, np.ndarray]:
    """Per probe column, the samples at times ``t_s`` recorded while its mount may have been moving
    (``t0 < t <= t0 + duration`` of each ``probe_recentre`` event stating a window); {} when none
    does."""
    t = np.asarray(t_s, dtype=np.float64)
    out: dict[str, np.ndarray] = {}
    for ev in events:
        move = parse_recentre(ev.message) if ev.name == RECENTRE_EVENT else None
        if move is None or not move.has_window:
            continue
        mask = out.setdefault(move.column, np.zeros(t.shape[0], dtype=bool))
        mask[(t > move.t_start_s) & (t <= move.t_start_s + move.duration_s)] = True
    return out
