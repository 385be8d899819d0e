"""Plug-in terms in the equations of motion: compiling them and handing them to the kernel.

An effect may give a friction law, a force on the slider and state variables of its own as plain
Python functions (:meth:`rigctl.model.Effect.friction_term`, ``force_term``, ``state_rate``;
docs/effects.md, section 3). :func:`build_terms` compiles each with numba to the fixed signature of
its kind (``njit(signature, cache=True)``: the machine code is cached on disk next to the user's
file, between runs and worker processes) and bundles them for the kernel as tuples of first-class
functions (:func:`rigctl.model.kernel.general.advance_terms`). The kernel itself is compiled once
per number of terms of each kind, not per plug-in, and cached as well.

A model with active terms is integrated by the general path (classical RK4 throughout, docs/model.md
section 3, "Terms from plug-ins"); a model without any keeps the exact path, bit for bit.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit, types
from numba.core.errors import NumbaExperimentalFeatureWarning

from rigctl.errors import SimulationError
from rigctl.model.effects.base import Effect

_ARR = types.float64[:]
_F = types.float64
FRICTION_SIG = _F(_ARR, _F, _F, _F, _F, _F, _F, _ARR)
"""mu_eff = f(p, mu, x_m, v_m_s, t_s, fn_N, stick_s, z)"""
FORCE_SIG = _F(_ARR, _F, _F, _F, _F, _ARR)
"""force_N = f(p, x_m, v_m_s, t_s, fn_N, z)"""
RATE_SIG = types.void(_ARR, _F, _F, _F, _F, _ARR, _ARR)
"""f(p, x_m, v_m_s, t_s, fn_N, z, dz_dt) writes dz/dt"""
KINDS: dict[str, Any] = {"friction": FRICTION_SIG, "force": FORCE_SIG, "rate": RATE_SIG}


@contextmanager
def first_class_functions() -> Iterator[None]:
    """Silence numba's "First-class function type feature is experimental" while the general
    path's kernel is typed, compiled or called with the terms' tuple of functions.

    numba warns (NumbaExperimentalFeatureWarning) whenever it types a first-class function
    argument, i.e. on every call of :func:`rigctl.model.kernel.general.advance_terms`, not only
    when compiling. It is safe to ignore here: the kernel uses the feature only to call functions
    compiled to the fixed signatures above, and what it computes with them is tested
    (tests/model/test_plugin_terms.py: results against the library's built-in laws, errors,
    determinism, the on-disk cache). Only this warning, only this message, only inside the block:
    any other warning still shows. (``warnings.catch_warnings`` swaps the process's filter list,
    so a filter another thread adds while a block runs is lost when the block ends.)"""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*First-class function type feature is "
                                r"experimental", category=NumbaExperimentalFeatureWarning)
        yield


class PluginTermError(SimulationError):
    """A plug-in term raised or gave a non-finite value: the simulation of that model ends.

    A fit treats it as a failed point (it is a :class:`~rigctl.errors.SimulationError`)."""


@njit(FRICTION_SIG, cache=True)
def _same_friction(p: np.ndarray, mu: float, x: float, v: float, t: float, fn: float,
                   stick: float, z: np.ndarray) -> float:
    """The neutral friction term (a kind without terms still passes one function)."""
    return mu


@njit(FORCE_SIG, cache=True)
def _no_force(p: np.ndarray, x: float, v: float, t: float, fn: float, z: np.ndarray) -> float:
    """The neutral force term."""
    return 0.0


@njit(RATE_SIG, cache=True)
def _no_rate(p: np.ndarray, x: float, v: float, t: float, fn: float, z: np.ndarray,
             dz: np.ndarray) -> None:
    """The neutral state law (no state)."""


_NEUTRAL = {"friction": _same_friction, "force": _no_force, "rate": _no_rate}
_COMPILED: dict[tuple[int, str], Any] = {}


def compile_term(fn: Callable[..., Any], kind: str, origin: str) -> Any:
    """``fn`` compiled by numba to the signature of its kind (once per process; cached on disk)."""
    key = (id(fn), kind)
    hit = _COMPILED.get(key)
    if hit is not None and hit[0] is fn:
        return hit[1]
    py = getattr(fn, "py_func", fn)  # a function the user already decorated with @njit
    try:
        try:
            compiled = njit(KINDS[kind], cache=True)(py)
        except Exception:  # a function numba cannot cache (no importable module): compile it only
            compiled = njit(KINDS[kind], cache=False)(py)
    except Exception as exc:  # numba's typing errors are long: keep the first line
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise PluginTermError(f"{origin}: its {kind} term does not compile: {first}") from exc
    _COMPILED[key] = (fn, compiled)
    return compiled


@dataclass(frozen=True)
class Term:
    """One compiled term of one effect."""

    effect: str
    kind: str
    function: Any
    params: np.ndarray
    z_bounds: tuple[int, int]


@dataclass(frozen=True)
class TermSet:
    """The active plug-in terms of a model, ready for the kernel."""

    terms: tuple[Term, ...] = ()
    z0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    state_names: tuple[str, ...] = ()

    @property
    def active(self) -> bool:
        return bool(self.terms)

    def names(self) -> list[str]:
        return sorted({t.effect for t in self.terms})

    def bundle(self) -> tuple[Any, ...]:
        """(friction fns, their params, z bounds, force ..., rate ...) as the kernel takes them."""
        out: list[Any] = []
        for kind in KINDS:
            mine = [t for t in self.terms if t.kind == kind]
            if not mine:
                out += [(_NEUTRAL[kind],), (np.zeros(0),), np.zeros((1, 2), dtype=np.int64)]
                continue
            out.append(tuple(t.function for t in mine))
            out.append(tuple(t.params for t in mine))
            out.append(np.array([t.z_bounds for t in mine], dtype=np.int64).reshape(-1, 2))
        return tuple(out)

    def culprit(self, t_s: float, x_m: float, v_m_s: float, fn_N: float, mu: float,
                z: np.ndarray, why: str = "made the state non-finite") -> str:
        """Which term raises or is not finite at this state, in words (for the error line);
        ``why`` is what the kernel saw, said of the only term or of all when none fails here."""
        for term in self.terms:
            zs = z[term.z_bounds[0]:term.z_bounds[1]].copy()
            try:
                if term.kind == "friction":
                    val = term.function(term.params, mu, x_m, v_m_s, t_s, fn_N, 0.0, zs)
                elif term.kind == "force":
                    val = term.function(term.params, x_m, v_m_s, t_s, fn_N, zs)
                else:
                    dz = np.zeros_like(zs)
                    term.function(term.params, x_m, v_m_s, t_s, fn_N, zs, dz)
                    val = float(np.sum(dz))
            except Exception as exc:
                return f"plug-in '{term.effect}' ({term.kind} term) raised {type(exc).__name__}: {exc}"
            if not math.isfinite(float(val)):
                return f"plug-in '{term.effect}' ({term.kind} term) returned {float(val)}"
        if len(self.terms) == 1:
            only = self.terms[0]
            return f"plug-in '{only.effect}' ({only.kind} term) {why}"
        return f"plug-in terms of {', '.join(self.names())}: one {why}"


def build_terms(entries: Sequence[tuple[Effect, Mapping[str, float]]],
                base: Mapping[str, float]) -> TermSet:
    """Compile the terms of the effects whose terms are active at their values."""
    terms: list[Term] = []
    z0: list[float] = []
    names: list[str] = []
    for eff, values in entries:
        if not eff.has_terms() or not eff.terms_active(values, base):
            continue
        origin = f"effect '{eff.name}'"
        p = np.array([float(values[s.name]) for s in eff.params], dtype=np.float64)
        start = len(z0)
        init = tuple(float(v) for v in eff.initial_state(values))
        if len(init) != len(eff.state_names):
            raise PluginTermError(f"{origin}: initial_state gives {len(init)} values for "
                                  f"{len(eff.state_names)} state_names")
        z0 += init
        names += [f"{eff.name}.{n}" for n in eff.state_names]
        bounds = (start, len(z0))
        if eff.state_names and eff.state_rate() is None:
            raise PluginTermError(f"{origin}: declares state_names but no state_rate")
        for kind, fn in (("friction", eff.friction_term()), ("force", eff.force_term()),
                         ("rate", eff.state_rate())):
            if fn is not None:
                terms.append(Term(eff.name, kind, compile_term(fn, kind, origin), p, bounds))
    return TermSet(tuple(terms), np.array(z0, dtype=np.float64), tuple(names))
