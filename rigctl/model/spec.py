"""Model specification: a base (``paper`` or ``classic``) plus effects, with their parameter values.

``build_model`` is the one way to make a model; a :class:`ModelSpec` is immutable and turns itself into
the coefficient arrays of the compiled integrator (:meth:`ModelSpec.core_setup`).

Flat parameter names: base parameters by their name (``mu_s``); parameters of an effect that is part
of the base (``stress_evolution`` in ``paper``) by their own name too (``mu_smax``); parameters of an
added effect as ``effect.param`` (``rate_state.b``). Qualified names are accepted everywhere.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rigctl.model import layout
from rigctl.model.effects import LIBRARY, CoreParams, Effect
from rigctl.model.effects.stress_evolution import p_linear
from rigctl.model.friction_laws import mu_kinetic, mu_kinetic_base, mu_static
from rigctl.model.params import BASE_PARAMS, ParameterError, ParamInfo, check_values
from rigctl.model.terms import TermSet, build_terms

BASES: dict[str, tuple[str, ...]] = {
    "paper": ("stress_evolution",),
    "classic": (),
}
"""Base models: ``paper`` = Han et al. 2022 (Sec. 5); ``classic`` = uniform stress, constant
stiffness, mu_s/mu_k (the paper's model without ``stress_evolution``)."""

EffectLike = str | Effect | type[Effect]


@dataclass(frozen=True)
class EffectEntry:
    effect: Effect
    values: Mapping[str, float]
    in_base: bool


@dataclass(frozen=True)
class CoreSetup:
    """Everything the integrator needs, built from a ModelSpec."""

    cp: np.ndarray
    weights: np.ndarray
    """Element weight table (rows ``layout.W_*``, one column per element)."""
    p_tables: np.ndarray
    theta0_s: float
    slip_hooks: tuple[EffectEntry, ...]
    output_hooks: tuple[EffectEntry, ...]
    terms: TermSet = field(default_factory=TermSet)
    """The active plug-in terms (compiled); with any, the kernel takes the general path."""


@dataclass(frozen=True)
class ModelSpec:
    base: str
    base_values: Mapping[str, float]
    effects: tuple[EffectEntry, ...] = field(default_factory=tuple)

    # --- introspection ------------------------------------------------------------------------
    @property
    def n_elements(self) -> int:
        return int(self.base_values["n_elements"])

    @property
    def effect_names(self) -> list[str]:
        """Names of the added effects (not those that are part of the base)."""
        return [e.effect.name for e in self.effects if not e.in_base]

    def flat_name(self, entry: EffectEntry, param: str) -> str:
        return param if entry.in_base else f"{entry.effect.name}.{param}"

    def values(self) -> dict[str, float]:
        """All parameter values by flat name."""
        out = dict(self.base_values)
        for e in self.effects:
            for k, v in e.values.items():
                out[self.flat_name(e, k)] = v
        return out

    def general_path(self) -> bool:
        """Whether the kernel integrates this model by its general path (classical RK4
        throughout, docs/model.md): some effect's plug-in terms act at these values
        (:meth:`~rigctl.model.effects.base.Effect.terms_active`). The same model at other values
        can take the exact path, at a fraction of the cost."""
        return any(e.effect.has_terms() and e.effect.terms_active(e.values, self.base_values)
                   for e in self.effects)

    def parameter_table(self) -> list[ParamInfo]:
        rows = [
            ParamInfo(s.name, float(self.base_values[s.name]), s.lower, s.upper, s.unit, "base",
                      s.identify, s.doc, s.scales_with)
            for s in BASE_PARAMS
        ]
        for e in self.effects:
            for s in e.effect.params:
                rows.append(
                    ParamInfo(self.flat_name(e, s.name), float(e.values[s.name]), s.lower, s.upper,
                              s.unit, e.effect.name, s.identify, s.doc, s.scales_with)
                )
        return rows

    def with_values(self, updates: Mapping[str, float]) -> ModelSpec:
        """A copy with some parameters changed (flat or qualified names); checks bounds."""
        base_up: dict[str, float] = {}
        eff_up: dict[str, dict[str, float]] = {}
        for key, value in updates.items():
            target, pname = self._resolve(key)
            if target is None:
                base_up[pname] = value
            else:
                eff_up.setdefault(target, {})[pname] = value
        new_base = check_values(BASE_PARAMS, {**self.base_values, **base_up}, "base")
        entries = []
        for e in self.effects:
            vals = dict(e.values)
            vals.update(eff_up.get(e.effect.name, {}))
            entries.append(EffectEntry(e.effect, check_values(e.effect.params, vals,
                                                              e.effect.name), e.in_base))
        return ModelSpec(self.base, new_base, tuple(entries))

    def _resolve(self, key: str) -> tuple[str | None, str]:
        if "." in key:
            ename, pname = key.split(".", 1)
            for e in self.effects:
                if e.effect.name == ename:
                    if pname not in {p.name for p in e.effect.params}:
                        raise ParameterError(f"effect '{ename}' has no parameter '{pname}'")
                    return ename, pname
            raise ParameterError(f"parameter '{key}': effect '{ename}' is not in this model")
        if key in self.base_values:
            return None, key
        for e in self.effects:
            if e.in_base and key in {p.name for p in e.effect.params}:
                return e.effect.name, key
        known = sorted(self.values())
        raise ParameterError(f"unknown parameter '{key}' (known: {', '.join(known)})")

    # --- the integrator's view ----------------------------------------------------------------
    def core_setup(self) -> CoreSetup:
        n = self.n_elements
        cp = np.zeros(layout.N_PARAMS)
        bv = self.base_values
        cp[layout.P_M] = bv["m_kg"]
        cp[layout.P_C0] = bv["c0_N_s_per_m"]
        cp[layout.P_K0] = bv["k0_N_per_m"]
        cp[layout.P_KTS] = bv["kts_N_per_m"]
        cp[layout.P_MUS] = bv["mu_s"]
        cp[layout.P_MUK] = bv["mu_k"]
        # coefficients owned by effects start at their off values (the classic model)
        cp[layout.P_KT0] = bv["kts_N_per_m"]
        cp[layout.P_MUSMAX] = bv["mu_s"]
        cp[layout.P_SD] = 1.0
        cp[layout.P_RS_DC] = 1e-6
        cp[layout.P_RS_VREF] = 1e-5
        cp[layout.P_FNREF_MU] = 300.0
        cp[layout.P_FNREF_K] = 300.0
        cp[layout.P_KT_MULT] = 1.0
        core = CoreParams(cp)
        factors = np.ones(n)
        theta0 = 0.0
        for e in self.effects:
            e.effect.apply(core, e.values)
            lin = e.effect.linear_terms(e.values)
            if lin is not None:
                lin = lin.checked(f"effect '{e.effect.name}'")
                cp[layout.P_CINT] += lin.damping_N_s_per_m
                cp[layout.P_KPAR] += lin.stiffness_N_per_m
                cp[layout.P_KAPPA] += lin.normal_per_drive_force
            f = e.effect.element_threshold_factors(e.values, n)
            if f is not None:
                factors = factors * np.asarray(f, dtype=np.float64)
            theta = e.effect.initial_theta_s(e.values)
            if theta is not None:
                theta0 = float(theta)
        p_lin = p_linear(n, float(cp[layout.P_PSLOPE]))
        p_uni = np.full(n, 1.0 / n)
        weights = np.empty((layout.N_WROWS, n))
        weights[layout.W_INITIAL] = p_lin * factors
        weights[layout.W_STABLE] = p_uni * factors
        weights[layout.W_UNIFORM] = p_uni
        return CoreSetup(
            cp=cp,
            weights=weights,
            p_tables=np.vstack([p_lin, p_uni]),
            theta0_s=theta0,
            slip_hooks=tuple(e for e in self.effects if e.effect.has_slip_hook()),
            output_hooks=tuple(e for e in self.effects if e.effect.has_output_hook()),
            terms=build_terms([(e.effect, e.values) for e in self.effects], bv),
        )

    def invalid_reason(self, fn_range_N: tuple[float, float] = (0.0, 0.0)) -> str | None:
        """Why this model cannot stick-slip, in one line; None when it can.

        Kinetic friction must stay below static friction: mu_k < mu_s of the base, what each
        effect states for its own parameters (:meth:`Effect.invalid_reason`), and, with the
        engine's own friction laws (so coefficients set by any effect or plug-in count), mu_k at
        V = 0 at most mu_s of either stage at the lowest and highest normal force of
        ``fn_range_N``. The engine does not finish a run that breaks it. Against the initial
        stage the kinetic friction is taken without its Stribeck part: that part rises to the
        stable stage's mu_s at V = 0 by construction, and the kernel caps it during a slip by
        what the elements carry (``kernel.nonlinear_slip.cap_stribeck``), so it cannot hold a
        slip; with ``load_dependent_friction`` raising mu_s with the load above an initial
        stage's mu_s,max, the whole law would refuse every Stribeck velocity (a held-out
        campaign's own generating model, which the engine runs, failed it).
        """
        bv = self.base_values
        if bv["mu_k"] >= bv["mu_s"]:
            return f"mu_k ({bv['mu_k']:g}) reaches mu_s ({bv['mu_s']:g})"
        for e in self.effects:
            reason = e.effect.invalid_reason(e.values, bv)
            if reason is not None:
                return reason
        cp = self.core_setup().cp
        # at Fn = 0 the load-dependent power laws degenerate; an unloaded end is checked at 1 mN
        for fn in sorted({max(fn_range_N[0], 1e-3), max(fn_range_N[1], 1e-3)}):
            for stage in (1, 0):
                mk = (mu_kinetic if stage == 1 else mu_kinetic_base)(cp, fn, 0.0, 0.0)
                ms = mu_static(cp, stage, fn, 0.0)
                if mk > ms:
                    return (f"kinetic friction {mk:.6g} exceeds the static friction {ms:.6g} of "
                            f"the {('initial', 'stable')[stage]} stage at Fn = {fn:g} N")
        return None

    def describe(self) -> str:
        added = ", ".join(self.effect_names) or "none"
        return f"base={self.base}, effects={added}"


def _as_effect(item: EffectLike, registry: Mapping[str, type[Effect]]) -> Effect:
    if isinstance(item, Effect):
        return item
    if isinstance(item, type) and issubclass(item, Effect):
        return item()
    if isinstance(item, str):
        cls = registry.get(item)
        if cls is None:
            raise ParameterError(
                f"unknown effect '{item}' (known: {', '.join(sorted(registry))})"
            )
        return cls()
    raise ParameterError(f"not an effect: {item!r}")


def effect_names() -> list[str]:
    """The canonical names of the effect library."""
    return list(LIBRARY)


def build_model(
    base: str = "paper",
    effects: Iterable[EffectLike] = (),
    params: Mapping[str, float] | None = None,
    effect_params: Mapping[str, Mapping[str, float]] | None = None,
    registry: Mapping[str, type[Effect]] | None = None,
) -> ModelSpec:
    """Build a model from a base, effects (names, instances or classes) and parameter overrides."""
    if base not in BASES:
        raise ParameterError(f"unknown base '{base}' (known: {', '.join(BASES)})")
    reg: dict[str, type[Effect]] = dict(LIBRARY)
    if registry:
        reg.update(registry)
    base_values = check_values(BASE_PARAMS, {}, "base")
    entries: list[EffectEntry] = []
    seen: set[str] = set()
    items: list[tuple[EffectLike, bool]] = [(name, True) for name in BASES[base]]
    items += [(e, False) for e in effects]
    for item, in_base in items:
        eff = _as_effect(item, reg)
        if not eff.name:
            raise ParameterError(f"effect {type(eff).__name__} has no name")
        if eff.name in seen:
            if eff.name in BASES[base]:
                continue  # already part of the base
            raise ParameterError(f"effect '{eff.name}' given twice")
        seen.add(eff.name)
        vals = check_values(eff.params, eff.default_values(base_values), eff.name)
        entries.append(EffectEntry(eff, vals, in_base))
    spec = ModelSpec(base, base_values, tuple(entries))
    updates: dict[str, float] = dict(params or {})
    for ename, pvals in (effect_params or {}).items():
        if ename not in seen:
            raise ParameterError(f"parameters given for effect '{ename}', which is not in the model")
        for k, v in pvals.items():
            updates[f"{ename}.{k}"] = v
    return spec.with_values(updates) if updates else spec


def model_with_effects_off(spec: ModelSpec, names: Sequence[str]) -> ModelSpec:
    """The same model with the named effects set to their off values (for reduction tests)."""
    updates: dict[str, float] = {}
    for e in spec.effects:
        if e.effect.name in names:
            for k, v in e.effect.off_values(spec.base_values).items():
                updates[spec.flat_name(e, k)] = v
    return spec.with_values(updates)
