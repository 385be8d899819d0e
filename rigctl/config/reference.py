"""The reference table of every configuration key, generated from the schema.

docs/configuration.md embeds this table; a test checks that it is current. Regenerate it with
``python -m rigctl.config.reference``.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Iterator
from typing import Any, Literal

import tomli_w

from rigctl.config.fields import setting_of
from rigctl.config.schema import RigConfig


def reference_rows(cls: type = RigConfig, prefix: str = "") -> Iterator[tuple[str, str, str, str]]:
    """``(dotted key, default as TOML, unit, meaning)`` for every leaf key, in schema order."""
    hints = typing.get_type_hints(cls)
    default = cls()
    for f in dataclasses.fields(cls):
        kind = hints[f.name]
        key = prefix + f.name
        if dataclasses.is_dataclass(kind):
            yield from reference_rows(kind, key + ".")  # type: ignore[arg-type]
            continue
        info = setting_of(cls, f)
        yield key, _toml_value(getattr(default, f.name)), info.unit, _meaning(info.doc, kind, info)


def markdown_reference() -> str:
    """The reference as a Markdown table."""
    lines = ["| key | default | unit | meaning |", "| --- | --- | --- | --- |"]
    for key, default, unit, meaning in reference_rows():
        lines.append(f"| `{key}` | `{default}` | {unit} | {meaning} |")
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, tuple):
        value = list(value)
    text = tomli_w.dumps({"v": value}).strip()
    return text.removeprefix("v = ").replace("|", "\\|")


def _meaning(doc: str, kind: Any, info: Any) -> str:
    parts = [doc]
    if typing.get_origin(kind) is Literal:
        parts.append("One of " + ", ".join(f"`{c}`" for c in typing.get_args(kind)) + ".")
    bounds = []
    if info.gt is not None:
        bounds.append(f"> {info.gt:g}")
    if info.ge is not None:
        bounds.append(f">= {info.ge:g}")
    if info.le is not None:
        bounds.append(f"<= {info.le:g}")
    if bounds:
        parts.append("Bounds: " + ", ".join(bounds) + ".")
    return " ".join(p for p in parts if p).replace("|", "\\|")


if __name__ == "__main__":
    print(markdown_reference(), end="")
