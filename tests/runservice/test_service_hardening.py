"""The run service: a silent connection blocks no one, the key file is made fresh in a private
folder, a malformed message is refused in one line (issue 35 item 11 and Low)."""

from __future__ import annotations

import math
import os
import socket
import stat
import threading
import time
from collections.abc import Iterator
from multiprocessing.connection import Client, Connection
from pathlib import Path
from typing import Any

import pytest

from rigctl.config.loader import default_config
from rigctl.rigs import open_rig
from rigctl.runservice import auth
from rigctl.runservice.private import ServiceFolderError
from rigctl.runservice.server import RunService
from rigctl.runservice.wire import Address

OTHER_UID = 54321
"""Another user (the tests run as root, which may chown a file to anyone)."""


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "svc"
    d.mkdir(mode=0o700)
    return d


@pytest.fixture
def service(folder: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[RunService]:
    monkeypatch.setattr(auth, "AUTH_TIMEOUT_S", 1.0)
    with open_rig("sim", default_config(), speed=math.inf) as rig:
        svc = RunService(rig, "sim", Address(folder), idle_exit_s=60.0)
        thread = threading.Thread(target=svc.serve, daemon=True)
        thread.start()
        deadline = time.monotonic() + 20
        while not Path(svc.address.socket).exists():
            assert time.monotonic() < deadline, "the service did not listen"
            time.sleep(0.02)
        yield svc
        svc.stop("test over")
        thread.join(30)


def _connect(address: Address, timeout_s: float) -> Connection | None:
    """A client connection within ``timeout_s`` (None if it blocked that long)."""
    got: list[Connection] = []
    t = threading.Thread(target=lambda: got.append(Client(address.socket, family="AF_UNIX",
                                                          authkey=address.key())), daemon=True)
    t.start()
    t.join(timeout_s)
    return got[0] if got else None


def _next(conn: Connection, kind: str, timeout_s: float = 5.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while conn.poll(max(0.0, deadline - time.monotonic())):
        k, payload = conn.recv()
        if k == kind:
            return payload
    raise AssertionError(f"no {kind!r} within {timeout_s} s")


def test_a_connection_that_never_answers_blocks_no_other_client(service: RunService) -> None:
    silent = socket.socket(socket.AF_UNIX)
    silent.connect(service.address.socket)  # accepted, and never answers the challenge
    try:
        time.sleep(0.1)  # the service is in its challenge of the silent one
        conn = _connect(service.address, timeout_s=0.8)  # before the silent one's time is up
        assert conn is not None, "a silent connection blocked the next client"
        _next(conn, "hello")
        conn.close()
        silent.settimeout(3.0)
        assert silent.recv(4096) is not None  # the challenge ...
        deadline = time.monotonic() + 3.0
        while silent.recv(4096):  # ... then the end: closed by the service after its time
            assert time.monotonic() < deadline
    finally:
        silent.close()


def test_a_wrong_key_is_refused_and_the_service_goes_on(service: RunService) -> None:
    from multiprocessing import AuthenticationError

    with pytest.raises(AuthenticationError):
        Client(service.address.socket, family="AF_UNIX", authkey=b"not the key")
    conn = _connect(service.address, timeout_s=3.0)
    assert conn is not None
    _next(conn, "hello")
    conn.close()


def test_a_malformed_message_is_refused_and_the_connection_goes_on(service: RunService) -> None:
    conn = _connect(service.address, timeout_s=3.0)
    assert conn is not None
    _next(conn, "hello")
    for bad, words in [(42, "a (kind, payload) pair"), ((1, 2), "kind is a string"),
                       (("start", "tlre"), "'start' needs a JobSpec"),
                       (("jog", None), "'jog' needs (axis, delta_m, velocity_m_s)"),
                       (("queue_add", {"protocol": "tlre"}), "'queue_add' needs a JobSpec")]:
        conn.send(bad)
        level, text = _next(conn, "log")
        assert level == "error" and "malformed message refused" in text and words in text, text
    conn.send_bytes(b"\x80\x04not a pickle")
    level, text = _next(conn, "log")
    assert "cannot be read" in text, text
    conn.send(("state", None))  # the reader is still there, and the service is not left busy
    state = _next(conn, "state")
    assert not state.busy
    conn.close()


def test_the_key_file_is_made_fresh_never_written_into(folder: Path) -> None:
    key_file = folder / "runservice.key"
    key_file.write_bytes(b"another user's file")
    os.chmod(key_file, 0o644)
    os.chown(key_file, OTHER_UID, OTHER_UID)
    key = Address(folder).new_key()
    st = os.stat(key_file)
    assert (st.st_uid, stat.S_IMODE(st.st_mode)) == (os.geteuid(), 0o600)
    assert key_file.read_bytes() == key and len(key) == 32
    assert Address(folder).key() == key
    assert [p.name for p in folder.iterdir()] == ["runservice.key"]  # no temporary file left


@pytest.mark.parametrize(("mode", "owner", "words"), [
    (0o777, None, "may be written by others (mode 0777)"),
    (0o1777, None, "(sticky folders such as /tmp included)"),
    (0o770, None, "may be written by others (mode 0770)"),
    (0o700, OTHER_UID, f"belongs to uid {OTHER_UID}"),
])
def test_a_folder_others_may_write_is_refused(folder: Path, mode: int, owner: int | None,
                                              words: str) -> None:
    os.chmod(folder, mode)
    if owner is not None:
        os.chown(folder, owner, owner)
    with pytest.raises(ServiceFolderError, match=words.replace("(", r"\(").replace(")", r"\)")):
        Address(folder).new_key()
    assert not (folder / "runservice.key").exists()


def test_a_key_planted_by_another_user_is_never_used(folder: Path) -> None:
    key_file = folder / "runservice.key"
    Address(folder).new_key()
    os.chown(key_file, OTHER_UID, OTHER_UID)
    with pytest.raises(ServiceFolderError, match=f"belongs to uid {OTHER_UID}"):
        Address(folder).key()
    os.chown(key_file, os.geteuid(), os.getegid())
    os.chmod(key_file, 0o644)
    with pytest.raises(ServiceFolderError, match="mode 0644"):
        Address(folder).key()


@pytest.mark.slow
def test_the_service_refuses_an_open_folder_in_one_line_before_the_rig_opens(tmp_path: Path) -> None:
    import subprocess
    import sys

    open_folder = tmp_path / "open"
    open_folder.mkdir()
    os.chmod(open_folder, 0o1777)
    proc = subprocess.run([sys.executable, "-m", "rigctl.runservice", "--dir", str(open_folder)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "may be written by others" in proc.stderr, proc.stderr
