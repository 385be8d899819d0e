"""Rank candidate effects by evidence and reach a verdict.

For each candidate the base model plus the effect is identified by the one search
(:mod:`rigctl.workbench.search`).
Evidence is the Bayesian information criterion (Schwarz, Ann. Stat. 6, 1978) with the number of slip
events n as the sample count and the event-aware error E (:mod:`rigctl.workbench.metrics`) as the
residual scale:

    BIC = n ln(E^2) + k ln(n),     delta_BIC = n ln(E_cand^2 / E_base^2) + (k_cand - k_base) ln(n).

A candidate is *significant* when delta_BIC <= -10 ("very strong" evidence on the scale of Kass &
Raftery, JASA 90, 1995), it removes at least 10 % of the error (so that a huge campaign cannot
make a negligible improvement look decisive) and E^2 falls by at least 0.5 (E is in units of the
measured scatter: a model already within the scatter has nothing left for an effect to explain, however
large the ratio of two small errors). Verdict:

* ``none`` - no candidate is significant: nothing earns its parameters;
* ``indistinguishable`` - the best significant candidates are within 6 in BIC of each other (Kass &
  Raftery's "strong"): the data cannot tell them apart, and the protocols that reveal them are
  suggested (each effect declares its ``reveal_protocol``);
* otherwise the best candidate's name.

**What the library does not explain.** A named effect should remove at least half of the error
(HALVING); where the best one removes less, or none is significant while the error stays well above
the scatter (E^2 > STRUCTURED_E2) with a structured residual, the verdict says so in words, with
the residual that stays: ``none of the library explains: ...`` (:attr:`Verdict.unexplained`),
instead of leaving the nearest effect to stand for it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

from rigctl.workbench.model_choice import effect_class

SIGNIFICANT_DELTA_BIC = -10.0
MIN_ERROR_REDUCTION = 0.10
MIN_E2_REDUCTION = 0.5
INDISTINGUISHABLE_DELTA_BIC = 6.0
HALVING = 0.5
"""A named effect explains most of a misfit when it removes at least this fraction of the error."""
STRUCTURED_E2 = 4.0
"""E^2 above this (twice the scatter) counts as a misfit to explain, not noise."""


@dataclass
class CandidateScore:
    """One candidate's evidence."""

    effect: str
    error: float
    error_reduction: float
    delta_bic: float
    significant: bool
    n_params: int
    explains: str = ""
    values: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, object]:
        return {
            "effect": self.effect,
            "error": _num(self.error),
            "error_reduction": _num(self.error_reduction),
            "delta_bic": _num(self.delta_bic),
            "significant": self.significant,
            "explains": self.explains,
        }


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def delta_bic(e_base: float, e_cand: float, n_events: int, extra_params: int) -> float:
    n = max(n_events, 2)
    if not (e_base > 0 and e_cand > 0):
        return math.nan
    return n * math.log(e_cand**2 / e_base**2) + extra_params * math.log(n)


def score_candidate(
    effect: str, e_base: float, e_cand: float, n_events: int, extra_params: int
) -> CandidateScore:
    dbic = delta_bic(e_base, e_cand, n_events, extra_params)
    reduction = (e_base - e_cand) / e_base if e_base > 0 else math.nan
    significant = (
        math.isfinite(dbic) and dbic <= SIGNIFICANT_DELTA_BIC and reduction >= MIN_ERROR_REDUCTION
        and e_base**2 - e_cand**2 >= MIN_E2_REDUCTION
    )
    return CandidateScore(effect, e_cand, reduction, dbic, significant, extra_params)


class VerdictKind(StrEnum):
    """What a diagnosis concluded (module docstring): one effect, none, or indistinguishable."""

    EFFECT = "effect"
    NONE = "none"
    INDISTINGUISHABLE = "indistinguishable"


@dataclass
class Verdict:
    verdict: str
    """As reported (text, JSON, report): the effect's name, ``none`` or ``indistinguishable``."""
    candidates: list[str]
    suggest: str | None
    unexplained: str = ""
    """What no library effect explains (module docstring), in words; empty when nothing is left."""
    runs: list[dict[str, object]] = field(default_factory=list)
    """The suggestion as runnable protocols (:func:`suggest_runs`), for ``indistinguishable``."""

    @property
    def kind(self) -> VerdictKind:
        """The kind of verdict (:attr:`verdict` is an effect's name for :attr:`VerdictKind.EFFECT`)."""
        if self.verdict in (VerdictKind.NONE, VerdictKind.INDISTINGUISHABLE):
            return VerdictKind(self.verdict)
        return VerdictKind.EFFECT


def rank(scores: Sequence[CandidateScore]) -> list[CandidateScore]:
    """Best evidence first (lowest delta BIC; failed fits last)."""
    return sorted(scores, key=lambda s: (not math.isfinite(s.delta_bic), s.delta_bic))


def verdict(ranked: Sequence[CandidateScore], effect_files: tuple[str, ...] = (),
            protocols_present: Sequence[str] = ()) -> Verdict:
    sig = [s for s in ranked if s.significant]
    if not sig:
        return Verdict(VerdictKind.NONE, [], None)
    best = sig[0]
    close = [s for s in sig[1:] if s.delta_bic - best.delta_bic < INDISTINGUISHABLE_DELTA_BIC]
    if not close:
        return Verdict(best.effect, [], None)
    names = [best.effect] + [s.effect for s in close]
    return Verdict(VerdictKind.INDISTINGUISHABLE, names,
                   suggest_protocol(names, effect_files, protocols_present),
                   runs=suggest_runs(names, effect_files))


def unexplained_text(best: CandidateScore | None, e_base: float,
                     residual: Sequence[str]) -> str:
    """``none of the library explains: ...`` when the best candidate removes less than HALVING of
    a structured misfit, else empty. ``residual``: the discrepancies that stay (with the best
    candidate added, if there is one)."""
    if e_base**2 <= STRUCTURED_E2 or not residual:
        return ""
    if best is not None and math.isfinite(best.error_reduction) \
            and best.error_reduction >= HALVING:
        return ""
    lead = "none of the library explains"
    if best is not None and math.isfinite(best.error_reduction) and best.error_reduction > 0:
        lead = (f"none of the library explains most of it (the best, {best.effect}, removes "
                f"{best.error_reduction:.0%} of the error)")
    return f"{lead}: " + "; ".join(residual[:3])


def suggest_runs(names: Sequence[str], effect_files: tuple[str, ...] = (),
                 fn_N: float | None = None) -> list[dict[str, object]]:
    """Each effect's ``reveal_run`` as a protocol run of this rig: ``{"reveals", "protocol",
    "parameters", "command"}``, one per distinct run (``rigctl run PROTOCOL --param ...`` runs it,
    dry run, limits and safe state included). ``fn_N`` (the campaign's normal force) is added
    where the protocol takes one and it does not set its own."""
    out: list[dict[str, object]] = []
    seen: set[tuple[str, tuple[tuple[str, str], ...]]] = set()
    for name in names:
        cls = effect_class(name, effect_files)
        run = getattr(cls, "reveal_run", None) if cls else None
        if not run:
            continue
        protocol, params = run[0], tuple(run[1])
        if (protocol, params) in seen:
            continue
        seen.add((protocol, params))
        parameters = dict(params)
        if fn_N is not None and protocol != "force_sweep" and "fn_N" not in parameters:
            parameters["fn_N"] = f"{fn_N:.4g}"
        command = " ".join(["rigctl", "run", protocol,
                            *(f"--param {k}={v}" for k, v in parameters.items())])
        out.append({"reveals": name, "protocol": protocol, "parameters": parameters,
                    "command": command})
    return out


def suggest_protocol(names: Sequence[str], effect_files: tuple[str, ...] = (),
                     protocols_present: Sequence[str] = ()) -> str:
    """The experiments that would separate the effects (each effect's ``reveal_protocol``)."""
    parts: list[str] = []
    seen: set[str] = set()
    for name in names:
        cls = effect_class(name, effect_files)
        proto = (getattr(cls, "reveal_protocol", "") or "").strip() if cls else ""
        if not proto or proto in seen:
            continue
        seen.add(proto)
        parts.append(f"{proto} (reveals {name})")
    if not parts:
        return "vary the conditions the candidates depend on: normal force, velocity, hold time"
    text = "run " + "; or ".join(parts)
    if protocols_present:
        text += f" - this campaign has: {', '.join(protocols_present)}"
    return text

