"""Each connection to the run service is authenticated in its own thread, within a time limit.

:class:`multiprocessing.connection.Listener` with an ``authkey`` runs the HMAC challenge inside
``accept()``: one connection that never answers it blocked every later client (a window wanting
to abort a run included) for as long as it stayed open. The service's listener takes no key;
:func:`authenticate` runs the same challenge (``deliver_challenge``, ``answer_challenge``) on one
connection, and a timer shuts the connection down when it has not answered in time.
"""

from __future__ import annotations

import contextlib
import os
import socket
import threading
from multiprocessing import AuthenticationError
from multiprocessing.connection import Connection, answer_challenge, deliver_challenge

AUTH_TIMEOUT_S = 5.0
"""Time a new connection has to answer the challenge (a window answers within milliseconds)."""


def authenticate(conn: Connection, key: bytes, timeout_s: float | None = None) -> str | None:
    """None when ``conn`` answered the challenge with ``key`` within ``timeout_s`` (default
    AUTH_TIMEOUT_S); else why not (the connection is then closed)."""
    if timeout_s is None:
        timeout_s = AUTH_TIMEOUT_S
    sock = socket.socket(fileno=os.dup(conn.fileno()))  # to shut the connection down from a timer
    lock = threading.Lock()
    state = {"done": False, "timed_out": False}

    def expire() -> None:
        with lock:
            if state["done"]:
                return
            state["timed_out"] = True
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)  # the blocked read returns: EOFError

    timer = threading.Timer(timeout_s, expire)
    timer.daemon = True
    timer.start()
    why: str | None = None
    try:
        deliver_challenge(conn, key)
        answer_challenge(conn, key)
    except AuthenticationError as exc:
        why = f"failed authentication ({exc})"
    except (OSError, EOFError, ValueError) as exc:
        why = f"closed during authentication ({type(exc).__name__})"
    finally:
        with lock:
            state["done"] = True
        timer.cancel()
        sock.close()
    if state["timed_out"]:
        why = f"did not answer the authentication challenge within {timeout_s:g} s"
    if why is not None:
        with contextlib.suppress(OSError):
            conn.close()
    return why
