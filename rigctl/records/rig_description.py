"""What a record says about the rig it came from: parameters to fix or bound, what was measured.

A rig description comes with the data, as ``# key: value`` metadata lines of a CSV file
(docs/csv-format.md) or as ``rig_description.toml`` in the campaign folder (:mod:`rigctl.io.load`
merges it into every run of the folder). Keys:

* ``rig.<parameter>``: a model parameter (as ``rigctl model compare`` lists them: ``m_kg``,
  ``k0_N_per_m``, ``c0_N_s_per_m``, ``mu_s``, ...) as a number, which **fixes** it (the fit leaves it
  alone), or as ``lo..hi``, which **bounds** it (the fit stays inside).
* ``rig.delta_measured``: ``no`` when the record has no displacement probes (the d1/d2 columns are
  filler); a constant column is recognised as such without it.

Every run of a campaign must agree on a key it states (one model is fitted to all of them).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from rigctl.data import DataError, MeasuredRun

PREFIX = "rig."
YES = ("yes", "true", "1")
NO = ("no", "false", "0")


@dataclass(frozen=True)
class RigDescription:
    fixed: dict[str, float] = field(default_factory=dict)
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    delta_measured: bool | None = None
    """None: not stated (judged from the probe columns)."""

    @property
    def empty(self) -> bool:
        return not self.fixed and not self.bounds and self.delta_measured is None

    def notes(self) -> list[str]:
        out = [f"{k} = {v:g} fixed by the rig description" for k, v in sorted(self.fixed.items())]
        out += [f"{k} bounded to [{lo:g}, {hi:g}] by the rig description"
                for k, (lo, hi) in sorted(self.bounds.items())]
        return out


def _number(text: str, key: str, source: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise DataError(f"rig description {key!r}: {text!r} is not a number", path=source or None) \
            from None
    if not math.isfinite(v):
        raise DataError(f"rig description {key!r}: {text!r} is not finite", path=source or None)
    return v


def parse(metadata: Mapping[str, str], source: str = "") -> RigDescription:
    """The rig description in one run's metadata (keys without the ``rig.`` prefix are ignored)."""
    fixed: dict[str, float] = {}
    bounds: dict[str, tuple[float, float]] = {}
    delta: bool | None = None
    for raw_key, raw in metadata.items():
        if not raw_key.startswith(PREFIX):
            continue
        key = raw_key[len(PREFIX):].strip()
        text = str(raw).strip()
        if key == "delta_measured":
            if text.lower() in YES:
                delta = True
            elif text.lower() in NO:
                delta = False
            else:
                raise DataError(f"rig description 'rig.delta_measured': {text!r} is not yes or no",
                                path=source or None)
        elif ".." in text:
            lo_t, hi_t = text.split("..", 1)
            lo, hi = _number(lo_t, raw_key, source), _number(hi_t, raw_key, source)
            if not lo < hi:
                raise DataError(f"rig description {raw_key!r}: empty range {text!r}",
                                path=source or None)
            bounds[key] = (lo, hi)
        else:
            fixed[key] = _number(text, raw_key, source)
    return RigDescription(fixed, bounds, delta)


def campaign_description(runs: Iterable[MeasuredRun]) -> RigDescription:
    """One description for a campaign; runs that state a key differently are refused."""
    merged_fixed: dict[str, float] = {}
    merged_bounds: dict[str, tuple[float, float]] = {}
    delta: bool | None = None
    seen: dict[str, str] = {}
    for run in runs:
        d = parse(run.metadata, run.source)
        items: list[tuple[str, object]] = [*d.fixed.items(), *d.bounds.items()]
        if d.delta_measured is not None:
            items.append(("delta_measured", d.delta_measured))
        for key, value in items:
            prev = ({**merged_fixed, **merged_bounds}.get(key)
                    if key != "delta_measured" else delta)
            if key in seen and prev != value:
                raise DataError(
                    f"rig description 'rig.{key}' differs between {seen[key]} and this file "
                    "(one model is fitted to a whole campaign)", path=run.source or None)
            seen.setdefault(key, run.source or "a run")
        merged_fixed.update(d.fixed)
        merged_bounds.update(d.bounds)
        if d.delta_measured is not None:
            delta = d.delta_measured
    return RigDescription(merged_fixed, merged_bounds, delta)


def check_names(desc: RigDescription, known: Iterable[str]) -> None:
    """Refuse a description that names a parameter the model does not have."""
    names = set(known)
    for key in [*desc.fixed, *desc.bounds]:
        if key not in names:
            raise DataError(f"rig description names unknown parameter 'rig.{key}' "
                            f"(known: {', '.join(sorted(names))})")
