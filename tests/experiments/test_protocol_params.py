"""Protocols declare their parameters once, as typed fields, and build from typed values."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from experiments.params import resolve
from experiments.protocols import PROTOCOLS, TlreParams
from experiments.runner import build_steps


@pytest.mark.parametrize("name", list(PROTOCOLS))
def test_param_defs_come_from_the_typed_fields(name: str) -> None:
    protocol = PROTOCOLS[name]
    fields = dataclasses.fields(protocol.values)
    hints = typing.get_type_hints(protocol.values)
    assert [d.name for d in protocol.params] == [f.name for f in fields]
    for d, f in zip(protocol.params, fields, strict=True):
        assert d.default == f.default
        kind = hints[f.name]
        if d.is_list:
            assert kind == tuple[float, ...]
        else:
            assert isinstance(d.default, kind)
        assert d.unit and d.doc


def test_build_reads_typed_values() -> None:
    seen: list[TlreParams] = []
    tlre = PROTOCOLS["tlre"]
    original = tlre.build
    try:
        object.__setattr__(tlre, "build", lambda p: seen.append(p) or original(p))
        params, steps = build_steps(tlre, {"repetitions": "2", "fn_N": "250"})
    finally:
        object.__setattr__(tlre, "build", original)
    (p,) = seen
    assert isinstance(p, TlreParams)
    assert p.repetitions == 2 and isinstance(p.repetitions, int)
    assert p.fn_N == 250.0 and p.preload_factor == 1.2
    assert params == dataclasses.asdict(p) == resolve(tlre.params, {"repetitions": "2", "fn_N": "250"},
                                                      "tlre")
    assert sum(s.describe().startswith("slide") for s in steps) == 2
