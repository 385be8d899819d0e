"""The rig's rated figures, written once: the drivers' force guard, the configuration's bounds and
the model's limit on commands to this rig all take them from here."""

from __future__ import annotations

RATED_NORMAL_FORCE_N = 800.0
"""Maximum load of the rig's normal loading stage (Han et al. 2022, Section 2.1)."""
