"""Reads damaged run files as ``info`` and ``export`` do, in a process of its own, so that a read
that hangs (inside the HDF5 library, where no timeout reaches) cannot hang the test suite.

Usage: python -m tests.storage.damaged_reader_proc INTACT_RUN_FILE

Reads the intact run file, prints ``ready``, then for each path read on stdin prints one line:
``refused <message>`` (a one-line :class:`DataError`), ``read <n>`` (n samples read, exactly the
intact run's first n), or ``wrong <what>`` (a traceback, a message of several lines, or samples
that differ from the intact run's).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from rigctl.data import DataError
from rigctl.storage import RunReader


def answer(path: Path, whole: dict[str, np.ndarray]) -> str:
    try:
        with RunReader(path) as r:
            r.summary()
            r.events()
            data = r.to_measured(validate=False).columns()
    except DataError as exc:
        text = str(exc)
        return f"wrong several lines: {text!r}" if "\n" in text else f"refused {text}"
    except Exception as exc:  # a traceback is a wrong answer
        return "wrong " + " ".join(f"{type(exc).__name__}: {exc}".split())
    n = data["t_s"].shape[0]
    for name, values in data.items():
        if n > whole[name].shape[0] or not np.array_equal(values, whole[name][:n]):
            return f"wrong {name} differs from the intact run in its first {n} samples"
    return f"read {n}"


def main(intact: str) -> None:
    with RunReader(Path(intact)) as r:
        whole = r.to_measured(validate=False).columns()
    print("ready", flush=True)
    for line in sys.stdin:
        print(answer(Path(line.strip()), whole), flush=True)


if __name__ == "__main__":
    main(sys.argv[1])
