"""Text from a file or a library error made safe to print on one line.

A damaged or foreign file can hold control bytes (an escape sequence would reach the terminal) and
HDF5's errors span several lines; messages are one line (docs/reliability.md).
"""

from __future__ import annotations

_KEEP = {"\n": "\n", "\t": "\t"}


def printable(text: str, *, keep_lines: bool = False) -> str:
    """``text`` with every control or non-printable character written as its escape (``\\x1b``);
    newlines and tabs stay when ``keep_lines``."""
    if text.isprintable():
        return text
    out = []
    for c in text:
        if c.isprintable() or (keep_lines and c in _KEEP):
            out.append(c)
        else:
            out.append(repr(c)[1:-1])
    return "".join(out)


def one_line(exc: BaseException | str, limit: int = 300) -> str:
    """An error (or text) as one printable line of at most ``limit`` characters."""
    if isinstance(exc, KeyError) and exc.args:  # str() of a KeyError is the repr of its text
        exc = str(exc.args[0])
    text = printable(" ".join(str(exc).split()))
    return text if len(text) <= limit else text[: limit - 3] + "..."
