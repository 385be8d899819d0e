"""The effect plug-in interface: what an effect is and the hooks through which it acts on the model.

An effect is a small class with a canonical ``name``, a ``summary``, parameter specs (SI units,
bounds, an ``off`` value at which it has no influence) and up to three hooks:

* :meth:`Effect.apply` - set or scale model coefficients before a run (``core`` below);
* :meth:`Effect.on_slip_end` - update coefficients after every global slip (wear, degradation...);
* :meth:`Effect.transform_output` - act on the recorded outputs (sensor or probe behaviour);

and terms of the equations of motion: :meth:`Effect.linear_terms`, a drag and a spring on the
slider and a coupling of the normal force, linear in the slider's state, which the exact path
integrates in closed form (:class:`LinearTerms`); and up to three plain Python functions that the engine
compiles with numba when the model is built (:mod:`rigctl.model.terms`):
:meth:`Effect.friction_term`, :meth:`Effect.force_term` and :meth:`Effect.state_rate` (with
:attr:`Effect.state_names`), integrated by the general path.

``core`` is a :class:`CoreParams`: the coefficients the compiled integrator reads, by name. Built-in
and user effects use exactly the same interface (docs/effects.md).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from rigctl.errors import SimulationError
from rigctl.model import layout
from rigctl.model.params import ParamSpec

if TYPE_CHECKING:
    from rigctl.model.result import SimResult

# Coefficient names a hook may read or set, mapped to slots of the kernel's parameter vector.
CORE_SLOTS: dict[str, int] = {
    "m_kg": layout.P_M,
    "c0_N_s_per_m": layout.P_C0,
    "k0_N_per_m": layout.P_K0,
    "kts_N_per_m": layout.P_KTS,
    "mu_s": layout.P_MUS,
    "mu_k": layout.P_MUK,
    "kt0_N_per_m": layout.P_KT0,
    "mu_smax": layout.P_MUSMAX,
    "p_slope": layout.P_PSLOPE,
    "stribeck_vs_m_per_s": layout.P_VS,
    "stribeck_d": layout.P_SD,
    "rs_a": layout.P_RS_A,
    "rs_b": layout.P_RS_B,
    "rs_dc_m": layout.P_RS_DC,
    "rs_v_ref_m_per_s": layout.P_RS_VREF,
    "alpha_s": layout.P_ALPHA_S,
    "alpha_k": layout.P_ALPHA_K,
    "fn_ref_mu_N": layout.P_FNREF_MU,
    "beta0": layout.P_BETA0,
    "beta_s": layout.P_BETAS,
    "fn_ref_k_N": layout.P_FNREF_K,
    "kt_multiplier": layout.P_KT_MULT,
    "dmu_s": layout.P_DMU_S,
    "dmu_k": layout.P_DMU_K,
    "threshold_spread": layout.P_SPREAD,
    "sensor_tau_s": layout.P_TAU_S,
}
# (the drag, the parallel spring and the normal coupling, slots P_CINT, P_KPAR and P_KAPPA, are not
# set by hooks: they are the sums of the effects' LinearTerms, one way to state them)


@dataclass(frozen=True)
class LinearTerms:
    """Terms of the equations of motion linear in the slider's state, which the exact path
    integrates in closed form (docs/model.md, section 3): a model with them keeps its speed.

    The slider's law of motion, with the drive force F_d = K0 (x_stage - X) + C0 (v_stage - V)
    (docs/model.md, section 1), becomes

        M X'' = F_d - F_interface(Fn_eff) - c V - k_p (X - X(0)),
        Fn_eff = Fn + kappa K0 (x_stage - X)

    where c, k_p and kappa are the sums over the model's effects. The drag and the coupling act
    while the specimens are in contact (they are properties of the interface); the spring ties the
    slider to the frame and acts always."""

    damping_N_s_per_m: float = 0.0
    """c: a dashpot in parallel with the interface, the force -c V on the slider [N s/m]"""
    stiffness_N_per_m: float = 0.0
    """k_p: a spring from the slider to the frame (a flexure, a cable), relaxed where the slider
    starts: the force -k_p (X - X(0)) on the slider, in contact or not [N/m]"""
    normal_per_drive_force: float = 0.0
    """kappa: the normal force the interface carries changes by kappa times the drive spring's
    force K0 (x_stage - X) (a moment arm tilting the loading frame) [-]"""

    def checked(self, origin: str) -> LinearTerms:
        """Itself, when every coefficient is a finite number; else SimulationError naming it."""
        for name in ("damping_N_s_per_m", "stiffness_N_per_m", "normal_per_drive_force"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not np.isfinite(v):
                raise SimulationError(f"{origin}: linear term {name} = {v!r} is not a finite number")
        return self


class CoreParams:
    """Named view of the integrator's coefficient vector (SI units)."""

    def __init__(self, vector: np.ndarray) -> None:
        self._v = vector

    def __getitem__(self, name: str) -> float:
        return float(self._v[self._slot(name)])

    def __setitem__(self, name: str, value: float) -> None:
        v = float(value)
        if not np.isfinite(v):
            raise SimulationError(f"core coefficient '{name}' set to a non-finite value {v}")
        self._v[self._slot(name)] = v

    @staticmethod
    def _slot(name: str) -> int:
        try:
            return CORE_SLOTS[name]
        except KeyError:
            raise KeyError(
                f"unknown core coefficient '{name}' (known: {', '.join(CORE_SLOTS)})"
            ) from None

    @property
    def vector(self) -> np.ndarray:
        return self._v


@dataclass(frozen=True)
class SlipContext:
    """What an ``on_slip_end`` hook learns about the global slip that just ended."""

    t_s: float
    """End of the slip [s]"""
    n_slips: int
    """Completed global slips so far, this one included (1 after the first)."""
    slip_m: float
    cumulative_slip_m: float
    fn_N: float
    peak_N: float
    trough_N: float
    x_start_m: float = 0.0
    """Slider position X at the start of the slip [m]"""
    x_end_m: float = 0.0
    """Slider position X at the end of the slip [m]"""
    peak_velocity_m_s: float = 0.0
    """Highest |V| during the slip [m/s]"""
    stick_s: float = 0.0
    """Stick time before the slip: from the end of the previous global slip (the start of the run
    for the first) to the start of this one [s]"""


class Effect:
    """Base class of every effect: one named physical mechanism added to the stick-slip model.

    Built-in effects and plug-ins (docs/effects.md) implement the same contract. To write one,
    subclass :class:`Effect` and follow these rules:

    1. Declare the class attributes: ``name`` (a new Python identifier; it names the effect in model
       specs, files and the CLI), ``summary`` (one line), ``signature`` (what the residual of a
       model without the effect looks like), ``reveal_protocol`` (the protocol that best shows
       it, in words) and ``reveal_run`` (the same as a run: a protocol name of ``rigctl run`` and
       its parameters as ``--param`` texts; optional) and ``params``: one
       :class:`~rigctl.model.params.ParamSpec` per parameter, SI unit in the name and in ``unit``
       (``"-"`` if none), finite bounds with the default inside them; a default typical of one
       rig's scale says which quantity it scales with (``scales_with``).
    2. Give every parameter an ``off`` value inside its bounds, or override :meth:`off_values` when
       "off" depends on the base parameters. At its off values the effect leaves every output of
       the model bit for bit as the model without it. At its defaults it changes something.
    3. Act on the model only through the hooks, and override only those the effect needs:
       :meth:`apply` sets the coefficients of ``core`` it owns before a run, :meth:`linear_terms`
       declares a drag, a spring or a normal coupling linear in the slider's state,
       :meth:`on_slip_end` updates coefficients after every global slip,
       :meth:`transform_output` changes the recorded outputs,
       :meth:`element_threshold_factors` scales the elements' static thresholds and
       :meth:`initial_theta_s` sets the rate-and-state variable at the start of a run. The engine
       calls :meth:`on_slip_end` and :meth:`transform_output` only when they are overridden (a
       run without slip hooks never stops at slips, so it is faster).
    4. Hooks are deterministic functions of their arguments: no random numbers, clock, files or
       global state. The same model, drive and seed give bit-identical results.
    5. Keep no run state on the instance: one instance serves every run of a model (and runs may
       be interleaved). What changes during a run lives in ``core``; :class:`SlipContext` gives
       the slip count and the cumulative slip distance. Hooks set coefficients (never add to the
       value they find) and only to finite numbers (:class:`CoreParams` refuses others).
    6. State which parameter values are physically impossible (:meth:`invalid_reason`), such as
       kinetic friction reaching static friction: fits skip such points instead of simulating
       them. Bounds say what is plausible; ``invalid_reason`` says what cannot be.
    7. Test the effect with :class:`rigctl.testing.EffectContract` (off-reduction, bounds,
       determinism); the built-in effects pass it.
    8. Terms in the equations of motion (:meth:`friction_term`, :meth:`force_term`,
       :meth:`state_rate`) are plain functions of numbers and float arrays that numba can compile
       (no Python objects, no globals that change); they read their parameters from ``p`` (this
       effect's values in the order of ``params``) and their own state variables from ``z``.
       While :meth:`terms_active` is False (at the off values) they are left out of the run.
       A term linear in the slider's state is declared by :meth:`linear_terms` instead: the model
       then keeps the exact path (``interface_damping``, ``normal_coupling``).
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    signature: ClassVar[str] = ""
    """What its absence looks like in the residual of a model without it (docs/effects.md)."""
    params: ClassVar[tuple[ParamSpec, ...]] = ()
    reveal_protocol: ClassVar[str] = ""
    """The protocol that best separates this effect from others (used in diagnosis advice)."""
    reveal_run: ClassVar[tuple[str, tuple[tuple[str, str], ...]] | None] = None
    """``reveal_protocol`` as a runnable suggestion: (protocol name for ``rigctl run``,
    ((parameter, value text), ...)); ``diagnose --json`` gives it so that it can be run."""

    def off_values(self, base: Mapping[str, float]) -> dict[str, float]:
        """Parameter values at which this effect leaves the model exactly as without it."""
        out: dict[str, float] = {}
        for p in self.params:
            if p.off is None:
                raise NotImplementedError(f"effect '{self.name}': parameter {p.name} has no off")
            out[p.name] = p.off
        return out

    def default_values(self, base: Mapping[str, float]) -> dict[str, float]:
        """Default parameter values (may depend on the base values)."""
        return {p.name: p.default for p in self.params}

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        """Set the coefficients this effect owns before a run starts."""

    def on_slip_end(
        self, core: CoreParams, values: Mapping[str, float], ctx: SlipContext
    ) -> None:
        """Update coefficients after each global slip (only called if overridden)."""

    def transform_output(self, result: SimResult, values: Mapping[str, float]) -> None:
        """Modify the recorded outputs in place (e.g. a probe's drift)."""

    def element_threshold_factors(
        self, values: Mapping[str, float], n_elements: int
    ) -> np.ndarray | None:
        """Optional per-element multipliers of the static thresholds (presliding); None = all 1."""
        return None

    def initial_theta_s(self, values: Mapping[str, float]) -> float | None:
        """Rate-and-state variable theta [s] at the start of a run; None leaves it to others (0)."""
        return None

    def invalid_reason(
        self, values: Mapping[str, float], base: Mapping[str, float]
    ) -> str | None:
        """Why these values (with the base parameters ``base``) are physically impossible, in one
        line naming the parameters; None when they are possible (the default)."""
        return None

    # --- terms in the equations of motion (docs/effects.md, section 3) --------------------------
    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms | None:
        """Terms linear in the slider's state (:class:`LinearTerms`: a drag -c V and a spring
        -k_p (X - X(0)) on the slider, a normal coupling kappa) at these values, or None. The
        engine adds those of every effect of the model into the coefficients of its exact path;
        zeros leave the model bit for bit as without them."""
        return None

    state_names: ClassVar[tuple[str, ...]] = ()
    """Names (with units) of this effect's own state variables, integrated by :meth:`state_rate`."""

    @staticmethod
    def friction_term() -> Callable[..., Any] | None:
        """A friction law ``mu_eff = f(p, mu, x_m, v_m_s, t_s, fn_N, stick_s, z)``, or None.

        Called at every step of the integrator with the coefficient the model computes without
        it (``mu``: the static one of a stuck or presliding element, the kinetic one in a global
        slip), the slider's position X and velocity V, the time, the normal force the interface
        carries, the element's stick time (0 while it slides) and this effect's state ``z``;
        returns the coefficient to use. Several friction terms apply in the model's order."""
        return None

    @staticmethod
    def force_term() -> Callable[..., Any] | None:
        """An extra force on the slider ``F = f(p, x_m, v_m_s, t_s, fn_N, z)`` [N] (positive
        along +X, added to M X''), or None."""
        return None

    @staticmethod
    def state_rate() -> Callable[..., Any] | None:
        """The evolution law of :attr:`state_names`: ``f(p, x_m, v_m_s, t_s, fn_N, z, dz_dt)``
        writes dz/dt into ``dz_dt`` (returns nothing), or None."""
        return None

    def initial_state(self, values: Mapping[str, float]) -> tuple[float, ...]:
        """Values of :attr:`state_names` at the start of a run (zeros unless overridden)."""
        return tuple(0.0 for _ in self.state_names)

    def terms_active(self, values: Mapping[str, float], base: Mapping[str, float]) -> bool:
        """Whether the terms act at these values: by default, unless every parameter is at its
        off value. An effect whose terms vanish while some parameters differ from off (a
        wavelength at zero amplitude) overrides it, so that the model keeps its exact path."""
        off = self.off_values(base)
        return any(values[p.name] != off[p.name] for p in self.params)

    @classmethod
    def has_terms(cls) -> bool:
        return (cls.friction_term is not Effect.friction_term
                or cls.force_term is not Effect.force_term
                or cls.state_rate is not Effect.state_rate)

    @classmethod
    def has_slip_hook(cls) -> bool:
        return cls.on_slip_end is not Effect.on_slip_end

    @classmethod
    def has_output_hook(cls) -> bool:
        return cls.transform_output is not Effect.transform_output
