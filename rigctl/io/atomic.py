"""Write a file all-or-nothing: to a temporary file in the same folder, then rename over the target.

``os.replace`` is atomic on POSIX and Windows when source and target are on the same file system,
which a sibling temporary file guarantees. A reader therefore sees either the old file or the
complete new one, never a half-written file; on any error the temporary file is removed.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

_NEW_FILE_MODE = 0o644


@contextlib.contextmanager
def atomic_text_writer(path: str | Path, *, encoding: str = "utf-8") -> Iterator[IO[str]]:
    """Yield a text stream; on a clean exit its content replaces ``path`` in one rename."""
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    try:
        # mkstemp makes the file private (0600); give it the target's mode, or rw-r--r--.
        os.chmod(tmp_name, target.stat().st_mode & 0o777 if target.exists() else _NEW_FILE_MODE)
        with os.fdopen(fd, "w", encoding=encoding, newline="") as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp_name, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise
