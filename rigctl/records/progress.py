"""Progress of a long analysis on the terminal (tqdm), or nothing.

A bar is shown on stderr when it is a terminal (or when forced), never in ``--json`` output. Steps
that stream frames report frames; the others report runs and passes.
"""

from __future__ import annotations

import sys
from types import TracebackType
from typing import Any

from tqdm import tqdm


class Bar:
    """A progress bar that may be disabled; a context manager."""

    def __init__(self, total: int, desc: str, unit: str, enabled: bool) -> None:
        self._bar: Any = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                              dynamic_ncols=True, mininterval=0.5) if enabled else None

    def update(self, n: int = 1) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()

    def __enter__(self) -> Bar:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class Progress:
    """Makes bars; ``Progress(False)`` makes silent ones."""

    def __init__(self, enabled: bool | None = None) -> None:
        self.enabled = sys.stderr.isatty() if enabled is None else enabled

    def bar(self, total: int, desc: str, unit: str = "it") -> Bar:
        return Bar(total, desc, unit, self.enabled)


SILENT = Progress(False)
