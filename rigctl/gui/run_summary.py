"""The Protocols tab's summary of a protocol with the values in its parameter table.

The protocol's own summary (``Protocol.summary``) describes its defaults ("300 N, 1.3 um/s, 3
repetitions"); once a value is edited it would be wrong. The summary shown is therefore built from
the steps the edited values make (``Protocol.steps``, the steps the run will execute), repeated
steps counted, so it follows every edit. No limit is checked here (that is the dry run's job).
"""

from __future__ import annotations

from experiments.errors import PlanError
from experiments.params import parse_assignments
from experiments.protocols import Protocol
from experiments.runner import build_steps

MAX_STEP_KINDS = 12
"""Distinct step descriptions listed before the rest is summed up as '…'."""


def purpose(protocol: Protocol) -> str:
    """What the protocol is for, without its default numbers: the summary's text before ':'."""
    head, sep, _ = protocol.summary.partition(":")
    return head if sep else protocol.name.replace("_", " ")


def values_summary(protocol: Protocol, values: dict[str, str], defaults: dict[str, str]) -> str:
    """Two lines: what the protocol does with these values (text by parameter name, as ``--param``;
    ``defaults`` as the table shows them) and its steps, or what is wrong with a value."""
    changed = {k: v for k, v in values.items() if v.strip() != defaults.get(k)}
    head = protocol.summary if not changed else (
        f"{purpose(protocol)}; edited: " + ", ".join(f"{k} = {v.strip()}" for k, v in changed.items()))
    try:
        _, steps = build_steps(protocol, parse_assignments([f"{k}={v}" for k, v in changed.items()]))
    except PlanError as exc:
        return f"{head}\nnot a valid set of values: {exc}"
    counts: dict[str, int] = {}
    for step in steps:
        d = step.describe()
        counts[d] = counts.get(d, 0) + 1
    kinds = [d + (f" (x{n})" if n > 1 else "") for d, n in counts.items()]
    shown = "; ".join(kinds[:MAX_STEP_KINDS]) + ("; …" if len(kinds) > MAX_STEP_KINDS else "")
    return f"{head}\n{len(steps)} steps: {shown}"
