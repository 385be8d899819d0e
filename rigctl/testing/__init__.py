"""Test helpers for people who extend rigctl: :class:`EffectContract` for effect plug-ins."""

from __future__ import annotations

from rigctl.testing.effect_contract import EffectContract

__all__ = ["EffectContract"]
