"""What a command sent to the run service must look like (:mod:`rigctl.runservice.wire`).

An authenticated client is this user's own, but a message it sends may still be malformed (a
version mismatch, a bug): it is refused with one line to that client and in the service's log,
and the connection goes on. Before, a malformed message killed the connection's reader thread
with a traceback, and ``("start", <not a JobSpec>)`` left the service busy for good.
"""

from __future__ import annotations

from typing import Any

from rigctl.runservice.wire import JobSpec

JOB_COMMANDS = ("start", "queue_add")
"""Commands whose payload is a :class:`JobSpec`."""


def command_problem(message: Any) -> str | None:
    """Why ``message`` is not a command the service can act on (None if it is)."""
    if not isinstance(message, tuple) or len(message) != 2:
        return f"a message is a (kind, payload) pair, got {_show(message)}"
    kind, payload = message
    if not isinstance(kind, str):
        return f"a message's kind is a string, got {_show(kind)}"
    if kind in JOB_COMMANDS and not isinstance(payload, JobSpec):
        return f"{kind!r} needs a JobSpec, got {_show(payload)}"
    if kind == "jog" and not (isinstance(payload, tuple | list) and len(payload) == 3
                              and isinstance(payload[0], str)
                              and all(isinstance(v, int | float) for v in payload[1:])):
        return f"'jog' needs (axis, delta_m, velocity_m_s), got {_show(payload)}"
    return None


def _show(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text[:60]}{'...' if len(text) > 60 else ''}"
