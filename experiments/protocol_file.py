"""Protocols from a Python file: ``rigctl run path/to/my_protocol.py``.

A protocol file is a Python module that defines one :class:`~experiments.protocols.Protocol` at
module level (named ``PROTOCOL`` if it defines more than one): its parameter class (a frozen
dataclass whose fields are made with :func:`~experiments.protocols.param`) and its ``build``
function returning the library's steps (``experiments.steps``, ``experiments.normal_load``). It is
loaded only from the explicit path given - never from a search path or a folder of plug-ins - and
runs through the same runner as the built-in protocols: the same parameter parsing, dry run against
the rig's limits, force guard and safe state.

The steps must be the library's own step classes: they are the ones whose ``plan`` checks the rig's
limits in the dry run. A file's own ``Step`` subclass is refused by the dry run (its ``plan`` could
skip the checks; the drivers would still refuse an out-of-limit move, but only once the run is
under way).

Errors are one line naming the file: a missing file, a syntax error (with its line), an exception
while the file runs (with the line in the file), no ``Protocol`` (or several and none named
``PROTOCOL``), a parameter field not made with ``param``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from experiments.errors import PlanError
from experiments.protocols import PROTOCOLS, Protocol
from experiments.steps import Step
from rigctl.errors import InputError

PROTOCOL_ATTRIBUTE = "PROTOCOL"
LIBRARY_STEP_MODULES = ("experiments.steps", "experiments.normal_load")


class ProtocolFileError(InputError):
    """A protocol file that cannot be used (one line, naming the file; exit code 2)."""


@dataclasses.dataclass(frozen=True)
class ProtocolFile:
    """A protocol loaded from a file, with where it came from (recorded in the run file)."""

    protocol: Protocol[Any]
    path: Path
    sha256: str

    def metadata(self) -> dict[str, str]:
        return {"protocol_file": str(self.path), "protocol_file_sha256": self.sha256}


def looks_like_a_file(argument: str) -> bool:
    """``rigctl run ARG``: a path (a ``.py`` name or anything with a folder separator) rather than
    the name of a built-in protocol."""
    return argument.endswith(".py") or "/" in argument or "\\" in argument


def load_protocol_file(path: str | Path) -> ProtocolFile:
    """The :class:`Protocol` defined by the Python file at ``path`` (see the module docstring)."""
    p = Path(path).expanduser()
    shown = str(path)
    if not p.exists():
        raise ProtocolFileError(f"protocol file {shown}: no such file")
    if not p.is_file():
        raise ProtocolFileError(f"protocol file {shown}: not a file")
    try:
        source = p.read_bytes()
    except OSError as exc:
        raise ProtocolFileError(f"protocol file {shown}: cannot be read ({exc.strerror})") from None
    p = p.resolve()
    digest = hashlib.sha256(source).hexdigest()
    module = _execute(p, shown, source, digest)
    protocol = _the_protocol(module, shown)
    if protocol.name in PROTOCOLS:
        raise ProtocolFileError(
            f"protocol file {shown}: '{protocol.name}' is the name of a built-in protocol; "
            "give the file's protocol a name of its own")
    _check_params(protocol, shown)
    checked = Protocol(protocol.name, protocol.summary, protocol.values,
                       _library_steps_only(protocol.build, shown))
    return ProtocolFile(checked, p, digest)


def _execute(path: Path, shown: str, source: bytes, digest: str) -> Any:
    try:
        code = compile(source, str(path), "exec")
    except SyntaxError as exc:
        raise ProtocolFileError(
            f"protocol file {shown}, line {exc.lineno}: syntax error: {exc.msg}") from None
    except ValueError as exc:  # e.g. null bytes
        raise ProtocolFileError(f"protocol file {shown}: not Python source ({exc})") from None
    # a module name of its own (never importable by name, never on sys.path); registered while it
    # runs because dataclasses look their module up in sys.modules
    name = f"rigctl_protocol_file_{digest[:16]}"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        exec(code, module.__dict__)
    except Exception as exc:
        del sys.modules[name]
        line = _line_in(path, exc)
        where = f", line {line}" if line is not None else ""
        raise ProtocolFileError(
            f"protocol file {shown}{where}: {type(exc).__name__}: {exc}") from None
    return module


def _line_in(path: Path, exc: BaseException) -> int | None:
    """The last line of ``path`` in the exception's traceback."""
    line = None
    for frame in traceback.extract_tb(exc.__traceback__):
        if Path(frame.filename) == path:
            line = frame.lineno
    return line


def _the_protocol(module: Any, shown: str) -> Protocol[Any]:
    named = getattr(module, PROTOCOL_ATTRIBUTE, None)
    if named is not None:
        if not isinstance(named, Protocol):
            raise ProtocolFileError(
                f"protocol file {shown}: {PROTOCOL_ATTRIBUTE} is a {type(named).__name__}, "
                "not a Protocol")
        return named
    found = {k: v for k, v in vars(module).items()
             if isinstance(v, Protocol) and not k.startswith("_") and v not in PROTOCOLS.values()}
    if not found:
        raise ProtocolFileError(
            f"protocol file {shown}: defines no Protocol (expected e.g. "
            f"{PROTOCOL_ATTRIBUTE} = Protocol(name, summary, ParamsClass, build))")
    if len(found) > 1:
        raise ProtocolFileError(
            f"protocol file {shown}: defines {len(found)} Protocols ({', '.join(found)}); "
            f"name the one to run {PROTOCOL_ATTRIBUTE}")
    return next(iter(found.values()))


def _check_params(protocol: Protocol[Any], shown: str) -> None:
    values = protocol.values
    if not (isinstance(values, type) and dataclasses.is_dataclass(values)):
        raise ProtocolFileError(
            f"protocol file {shown}: protocol '{protocol.name}': its parameters must be a "
            "dataclass (@dataclass(frozen=True) with fields made by param(...))")
    for f in dataclasses.fields(values):
        if "param" not in f.metadata:
            raise ProtocolFileError(
                f"protocol file {shown}: protocol '{protocol.name}': parameter '{f.name}' is not "
                "declared with param(default, unit, doc)")
    if not callable(protocol.build):
        raise ProtocolFileError(
            f"protocol file {shown}: protocol '{protocol.name}': build is not a function")


def _library_steps_only(build: Callable[[Any], list[Step]], shown: str
                        ) -> Callable[[Any], list[Step]]:
    """``build`` whose steps are checked to be instances of the library's step classes."""

    def checked(values: Any) -> list[Step]:
        steps = build(values)
        if not isinstance(steps, list | tuple):
            raise PlanError(f"protocol file {shown}: build returned a {type(steps).__name__}, "
                            "not a list of steps")
        for i, step in enumerate(steps, 1):
            cls = type(step)
            if not (isinstance(step, Step) and cls.__module__ in LIBRARY_STEP_MODULES):
                raise PlanError(
                    f"protocol file {shown}: step {i} is a {cls.__name__}, not one of the "
                    "library's steps (experiments.steps, experiments.normal_load), whose dry run "
                    "checks the rig's limits")
        return list(steps)

    return checked
