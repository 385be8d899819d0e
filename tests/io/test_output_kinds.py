"""``--force`` replaces only regular files: a device, a pipe or a socket is never replaced
(docs/reliability.md, "Output files")."""

from __future__ import annotations

import os
import socket
import stat
from collections.abc import Callable
from pathlib import Path

import pytest

from rigctl.errors import UsageError
from rigctl.io.outputs import check_output_file
from rigctl.storage.errors import StorageError
from rigctl.storage.preflight import check_output_path


def char_device(path: Path) -> None:
    """A node like /dev/null (major 1, minor 3) in a test folder (needs root's CAP_MKNOD)."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("creating a device node needs CAP_MKNOD")


def unix_socket(path: Path) -> None:
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(path))
    s.close()  # the socket file stays


KINDS: list[tuple[Callable[[Path], None], str]] = [
    (char_device, "a character device"),
    (os.mkfifo, "a named pipe"),
    (unix_socket, "a socket"),
]


@pytest.mark.parametrize(("make", "kind"), KINDS)
def test_force_never_replaces_what_is_not_a_regular_file(tmp_path: Path, make: Callable[[Path], None],
                                                         kind: str) -> None:
    node = tmp_path / "node"
    make(node)
    for force in (False, True):
        with pytest.raises(UsageError, match=f"--out .*node is {kind}, not a regular file"):
            check_output_file(node, "--out", force=force)
        with pytest.raises(StorageError, match=f"is {kind}, not a regular file"):
            check_output_path(node, overwrite=force, min_free_bytes=0)
    assert not stat.S_ISREG(os.stat(node).st_mode)


def test_a_link_is_judged_by_its_target(tmp_path: Path) -> None:
    node = tmp_path / "fifo"
    os.mkfifo(node)
    link = tmp_path / "link.h5"
    link.symlink_to(node)
    with pytest.raises(UsageError, match="a named pipe"):
        check_output_file(link, "--out", force=True)
    regular = tmp_path / "old.h5"
    regular.write_text("old")
    (tmp_path / "to_regular.h5").symlink_to(regular)
    check_output_file(tmp_path / "to_regular.h5", "--out", force=True)  # a file: replaced
