"""A run writer that fills its disk, for the full-disk tests, run as a separate process.

Usage: python full_disk_writer_proc.py PATH LIMIT_BYTES

The file-size limit stands in for a full disk (a write beyond it fails with EFBIG, as one fails
with ENOSPC on a full disk). Writes the default DAQ channels in blocks of 256 samples (values as
``tests.storage.conftest.block``), flushing after each, until a write fails; then closes the file
as ``failed``. Prints ``appended N`` for the samples handed to the writer and ``stopped: <error>``.
"""

from __future__ import annotations

import os
import resource
import signal
import sys


def main() -> None:
    path, limit = sys.argv[1], int(sys.argv[2])
    from rigctl.storage import DaqLayout, RunDescription, RunWriter
    from tests.storage.conftest import block

    writer = RunWriter(path, RunDescription(protocol="full-disk-test"),
                       DaqLayout(sample_rate_hz=1024.0), min_free_bytes=0)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    n = 0
    try:
        while True:
            writer.append_daq(block(n, 256), counter=n)
            n += 256
            writer.flush()
    except Exception as exc:
        print(f"appended {n}", flush=True)
        print(f"stopped: {type(exc).__name__}: {exc}", flush=True)
    try:
        writer.close("failed", "disk full")
    except Exception as exc:
        print(f"close: {type(exc).__name__}: {exc}", flush=True)
    os._exit(0)  # the HDF5 library may crash freeing a file whose close failed


if __name__ == "__main__":
    main()
