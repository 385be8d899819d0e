"""The run service's folder and key: only the user who runs it may write the one or read the other.

The key authenticates every connection (:mod:`multiprocessing.connection`'s HMAC challenge), and a
window trusts what an authenticated service sends it (pickles), so:

* the folder (socket, key, log) must be a folder owned by this user that no one else may write.
  A folder others may write is refused, **sticky folders such as /tmp included**: there another
  user cannot replace our files, but can plant a socket and a key of their own under the names a
  window looks for before the service starts. The default folder is a private one
  (``$XDG_RUNTIME_DIR/rigctl``, else ``<tmp>/rigctl-<uid>`` made with mode 0700);
* the key file is created fresh for each service: written to a new file (``O_EXCL``, mode 0600)
  and renamed over the old name, so an existing file (another user's, world-readable, a link) is
  replaced, never written into;
* a client reads a key only from a file owned by this user that no one else may read.
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path

from rigctl.errors import InputError

KEY_BYTES = 32


class ServiceFolderError(InputError):
    """A folder or key file of the run service that others could write or read (one line)."""


def check_private_folder(folder: Path) -> None:
    """Refuse (ServiceFolderError) a folder that is not this user's alone to write."""
    try:
        st = os.stat(folder)
    except OSError as exc:
        raise ServiceFolderError(f"run service folder {folder}: {exc.strerror}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise ServiceFolderError(f"run service folder {folder}: not a folder")
    if st.st_uid != os.geteuid():
        raise ServiceFolderError(f"run service folder {folder} belongs to uid {st.st_uid}, not to "
                                 f"this user (uid {os.geteuid()}): use a folder of your own")
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        sticky = " (sticky folders such as /tmp included)" if st.st_mode & stat.S_ISVTX else ""
        raise ServiceFolderError(
            f"run service folder {folder} may be written by others (mode "
            f"{stat.S_IMODE(st.st_mode):04o}){sticky}: its key and socket need a folder only you "
            "can write (chmod 700, or leave --dir out for the default private folder)")


def write_key(key_file: Path) -> bytes:
    """A fresh key in ``key_file`` (mode 0600, a new file renamed over the name: an existing file
    is replaced, never written into); the folder must be private (:func:`check_private_folder`)."""
    check_private_folder(key_file.parent)
    key = secrets.token_bytes(KEY_BYTES)
    tmp = key_file.with_name(f".{key_file.name}.{secrets.token_hex(8)}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), 0o600)
            f.write(key)
        os.replace(tmp, key_file)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return key


def read_key(key_file: Path) -> bytes:
    """The key in ``key_file``, refused (ServiceFolderError) unless the folder is private and the
    file is this user's and no one else's to read (a key planted by another user is never used)."""
    check_private_folder(key_file.parent)
    try:
        fd = os.open(key_file, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as exc:
        raise ServiceFolderError(f"run service key {key_file}: {exc.strerror}") from None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if st.st_uid != os.geteuid() or st.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
            raise ServiceFolderError(
                f"run service key {key_file} belongs to uid {st.st_uid} with mode "
                f"{stat.S_IMODE(st.st_mode):04o}: not a key of this user's service (it must be "
                "this user's, mode 0600)")
        return f.read()
