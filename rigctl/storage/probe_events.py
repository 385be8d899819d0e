"""The ``probe_recentre`` event: a probe's mount moved during a run, and by how much.

Written by the protocols' re-centring step (:mod:`experiments.recentre`) into the run file's event
table (docs/run-file.md), read by the analysis to stitch delta across the move
(:mod:`rigctl.analysis.delta_stitch`). One format, declared here: ``<column>: mount moved
<+-um> um (reading <+-um> -> <+-um> um)``, e.g. ``d1_m: mount moved +35.0120 um (reading +5.4000 ->
-29.6120 um)``. A positive move brings the probe towards its target: the readings drop by it.
"""

from __future__ import annotations

import re

RECENTRE_EVENT = "probe_recentre"
"""Event name of a mount move."""
NOT_RECENTRED_EVENT = "probe_not_recentred"
"""Event name of a re-centring that could not be made (the reason in the message)."""

_MESSAGE = re.compile(r"\s*(\w+):\s*mount moved\s+([+-]?(?:[0-9.]+(?:e[+-]?[0-9]+)?|nan))\s*um")


def recentre_message(column: str, moved_m: float, before_m: float, after_m: float) -> str:
    """The event message of a mount move of ``moved_m`` on the probe recorded as ``column``."""
    return (f"{column}: mount moved {moved_m * 1e6:+.4f} um (reading {before_m * 1e6:+.4f} -> "
            f"{after_m * 1e6:+.4f} um)")


def parse_recentre(message: str) -> tuple[str, float] | None:
    """(column, mount move [m]) of a ``probe_recentre`` message; the move is NaN when the message
    gives none (an operator's re-centring of unknown size); None when it is not such a message."""
    m = _MESSAGE.match(message)
    if m is None:
        return None
    value = m.group(2)
    return m.group(1), float(value) * 1e-6
