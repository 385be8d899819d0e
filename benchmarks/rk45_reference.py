"""The stick-slip model stepped the paper's way: ``scipy.integrate.solve_ivp(method="RK45")``.

An independent implementation of the ``paper``/``classic`` base model of docs/model.md (sections 1-2),
written from the documented physics only (it shares no code with the compiled engine in
``rigctl/model``; only the parameter *values* are read from the ModelSpec by name). It is the
baseline of the speed comparison and the independent correctness check of the engine.

State ``y = (X, V, x_0 .. x_{N-1})``: specimen position and velocity and the slider position of
each Jenkins element. Element i is a spring kt = Kt/N in series with a Coulomb slider, so its force is
``f_i = kt (X - x_i)``, clipped to its threshold ``tau_i = mu_static Fn P(i)``:

    X' = V
    V' = (K0 (x_stage - X) + C0 (v_stage - V) - sum_i f_i) / M        (Newton, docs/model.md sec. 1)
    x_i' = 0 (stuck)  or  V (presliding: the slider follows X, f_i stays at +-tau_i)

During a global slip (no element stuck) the interface force is ``sign * mu_k * Fn`` and every slider
follows X. The first global slip ends the initial stage: ``P_linear -> P_uniform``, ``Kt0 -> Kts``,
``mu_s,max -> mu_s`` (paper Sec. 5.2).

Discontinuities are handled the way MATLAB's ode45 is used for stick-slip: the right-hand side is
smooth between mode changes, ``events`` locate every mode change (a stuck element's force reaching
+-tau_i; a presliding element's velocity reversing; V returning to 0 in a global slip) and the
integration restarts from the event with the new modes. This is the *favourable* way to use RK45:
it keeps the solution at the solver's tolerance through every switch. The alternative (one smooth
RHS stepped with a small ``max_step``, no events) is first-order accurate at each switch and slower
for the same accuracy, so it would overstate the engine's speed-up.

Limits: constant Fn (the TLRE of the paper; any piecewise-linear x_stage, e.g. holds and reversals),
and no added effects. Anything else raises :class:`ReferenceModelError`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from rigctl.model import Drive, ModelSpec

_X_TOL_M = 1e-12
"""An element whose force is within kt * 1e-12 m of its threshold at an event switches with it
(the simultaneous switch of identical elements; same tolerance as the engine's)."""


class ReferenceModelError(ValueError):
    """The RK45 reference cannot represent this model or drive."""


@dataclass(frozen=True)
class RefParams:
    """Parameters of the base model (SI units), read by name from a ModelSpec."""

    m_kg: float
    c0_N_s_per_m: float
    k0_N_per_m: float
    kt0_N_per_m: float
    kts_N_per_m: float
    mu_smax: float
    mu_s: float
    mu_k: float
    p_slope: float
    n_elements: int

    @classmethod
    def from_spec(cls, spec: ModelSpec) -> RefParams:
        if spec.base not in ("paper", "classic") or spec.effect_names:
            raise ReferenceModelError(
                f"the RK45 reference covers the paper/classic base without added effects, "
                f"not {spec.describe()}"
            )
        v = spec.values()
        kts = v["kts_N_per_m"]
        return cls(
            m_kg=v["m_kg"], c0_N_s_per_m=v["c0_N_s_per_m"], k0_N_per_m=v["k0_N_per_m"],
            kt0_N_per_m=v.get("kt0_N_per_m", kts), kts_N_per_m=kts,
            mu_smax=v.get("mu_smax", v["mu_s"]), mu_s=v["mu_s"], mu_k=v["mu_k"],
            p_slope=v.get("p_slope", 0.0), n_elements=int(v["n_elements"]),
        )

    def shares(self, stage: int) -> np.ndarray:
        """Normal-load shares P(i): P_linear(i) = (1 + s (2 xi_i - 1))/N in the initial stage
        (xi_i = (i + 1/2)/N, element 0 at the back end; docs/model.md sec. 2), 1/N after."""
        n = self.n_elements
        if stage == 1:
            return np.full(n, 1.0 / n)
        xi = (np.arange(n) + 0.5) / n
        return (1.0 + self.p_slope * (2.0 * xi - 1.0)) / n

    def kt(self, stage: int) -> float:
        """Element stiffness Kt/N of the stage."""
        return (self.kt0_N_per_m if stage == 0 else self.kts_N_per_m) / self.n_elements

    def mu_static(self, stage: int) -> float:
        return self.mu_smax if stage == 0 else self.mu_s


@dataclass(frozen=True)
class RefEvent:
    """One global slip of the reference solution (same meaning as rigctl.model.SlipEvent)."""

    t_start_s: float
    t_end_s: float
    peak_N: float
    trough_N: float
    slip_m: float
    stage: str


@dataclass
class RefResult:
    """Samples at k / rate (SI units), the global slips, and the cost of the run."""

    t_s: np.ndarray
    ft_N: np.ndarray
    x_specimen_m: np.ndarray
    v_specimen_m_s: np.ndarray
    events: list[RefEvent]
    n_rhs: int
    """Right-hand-side evaluations."""
    n_segments: int
    """solve_ivp calls (one per smooth piece between events and drive knots)."""
    wall_s: float


@dataclass
class _Modes:
    """Discrete state between events."""

    stage: int = 0
    mode: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))
    gslip: bool = False
    sign: int = 1


class RK45Reference:
    """Step the base model with ``solve_ivp(RK45)`` and restart at every mode change."""

    def __init__(self, spec: ModelSpec, sample_rate_hz: float = 1024.0,
                 rtol: float = 1e-6, atol_m: float = 1e-12) -> None:
        """``atol_m`` is the absolute tolerance on positions; velocities get atol_m * 1e3 /s
        (the ~1 kHz ringing: a position error e means a velocity error ~ 7e3 e)."""
        if not (np.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ReferenceModelError(f"sample rate must be positive, got {sample_rate_hz}")
        if not (0 < rtol < 1 and atol_m > 0):
            raise ReferenceModelError(f"bad tolerances rtol={rtol}, atol_m={atol_m}")
        self.p = RefParams.from_spec(spec)
        self.sample_rate_hz = float(sample_rate_hz)
        self.rtol = rtol
        n = self.p.n_elements
        self.atol = np.full(n + 2, atol_m)
        self.atol[1] = atol_m * 1e3

    # --- the right-hand sides --------------------------------------------------------------------
    def _stick_rhs(self, xs0: float, vs: float, t0: float, fn: float, md: _Modes
                   ) -> Callable[[float, np.ndarray], np.ndarray]:
        p = self.p
        kt = p.kt(md.stage)
        thr = p.mu_static(md.stage) * fn * p.shares(md.stage)
        moving = (md.mode != 0).astype(np.float64)
        m, k0, c0 = p.m_kg, p.k0_N_per_m, p.c0_N_s_per_m

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            x = y[0]
            v = y[1]
            f = np.minimum(np.maximum(kt * (x - y[2:]), -thr), thr)
            dy = np.empty_like(y)
            dy[0] = v
            dy[1] = (k0 * (xs0 + vs * (t - t0) - x) + c0 * (vs - v) - f.sum()) / m
            dy[2:] = moving * v
            return dy

        return rhs

    def _slip_rhs(self, xs0: float, vs: float, t0: float, fn: float, md: _Modes
                  ) -> Callable[[float, np.ndarray], np.ndarray]:
        p = self.p
        f_int = md.sign * p.mu_k * fn
        m, k0, c0 = p.m_kg, p.k0_N_per_m, p.c0_N_s_per_m

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            v = y[1]
            dy = np.empty_like(y)
            dy[0] = v
            dy[1] = (k0 * (xs0 + vs * (t - t0) - y[0]) + c0 * (vs - v) - f_int) / m
            dy[2:] = v
            return dy

        return rhs

    # --- events ------------------------------------------------------------------------------------
    def _stick_events(self, fn: float, md: _Modes) -> list[Callable[[float, np.ndarray], float]]:
        p = self.p
        kt = p.kt(md.stage)
        thr = p.mu_static(md.stage) * fn * p.shares(md.stage)
        stuck = np.flatnonzero(md.mode == 0)
        thr_s = thr[stuck]
        events: list[Callable[[float, np.ndarray], float]] = []
        if stuck.size:
            def threshold(t: float, y: np.ndarray) -> float:
                return float(np.min(thr_s - np.abs(kt * (y[0] - y[2:][stuck]))))
            threshold.terminal = True  # type: ignore[attr-defined]
            threshold.direction = -1  # type: ignore[attr-defined]
            events.append(threshold)
        if np.any(md.mode > 0):
            def fwd_reversal(t: float, y: np.ndarray) -> float:
                return float(y[1])
            fwd_reversal.terminal = True  # type: ignore[attr-defined]
            fwd_reversal.direction = -1  # type: ignore[attr-defined]
            events.append(fwd_reversal)
        if np.any(md.mode < 0):
            def back_reversal(t: float, y: np.ndarray) -> float:
                return float(y[1])
            back_reversal.terminal = True  # type: ignore[attr-defined]
            back_reversal.direction = 1  # type: ignore[attr-defined]
            events.append(back_reversal)
        return events

    @staticmethod
    def _slip_end_event(sign: int) -> Callable[[float, np.ndarray], float]:
        def slip_end(t: float, y: np.ndarray) -> float:
            return float(y[1])
        slip_end.terminal = True  # type: ignore[attr-defined]
        slip_end.direction = -sign  # type: ignore[attr-defined]
        return slip_end

    # --- the run -----------------------------------------------------------------------------------
    def run(self, drive: Drive, duration_s: float | None = None) -> RefResult:
        """Simulate ``drive`` (or its first ``duration_s``); samples at k / rate as the engine."""
        if np.ptp(drive.fn_N) != 0.0:
            raise ReferenceModelError("the RK45 reference needs a constant normal force")
        t_total = drive.duration_s if duration_s is None else float(duration_s)
        if not (0.0 < t_total <= drive.duration_s):
            raise ReferenceModelError(f"duration {t_total} s outside the drive's span")
        p = self.p
        fn = float(drive.fn_N[0])
        n = p.n_elements
        n_out = int(np.floor(t_total * self.sample_rate_hz + 1e-9)) + 1
        t_out = np.arange(n_out) / self.sample_rate_hz
        xv = np.full((2, n_out), np.nan)
        y = np.zeros(n + 2)
        y[0] = drive.x_stage_m[0]
        y[2:] = y[0]  # every element stuck and unloaded
        md = _Modes(mode=np.zeros(n, dtype=np.int8))
        events: list[RefEvent] = []
        slip: _SlipRecord | None = None
        n_rhs = 0
        n_seg = 0
        t = 0.0
        io = 0
        stalls = 0
        wall0 = time.perf_counter()
        while t < t_total:
            j = min(int(np.searchsorted(drive.t_s, t, side="right")) - 1, drive.t_s.size - 2)
            t_knot = min(float(drive.t_s[j + 1]), t_total)
            vs = float((drive.x_stage_m[j + 1] - drive.x_stage_m[j])
                       / (drive.t_s[j + 1] - drive.t_s[j]))
            xs_t = float(drive.x_stage_m[j]) + vs * (t - float(drive.t_s[j]))
            if md.gslip:
                rhs = self._slip_rhs(xs_t, vs, t, fn, md)
                ev_funcs = [self._slip_end_event(md.sign)]
            else:
                rhs = self._stick_rhs(xs_t, vs, t, fn, md)
                ev_funcs = self._stick_events(fn, md)
            sol = solve_ivp(rhs, (t, t_knot), y, method="RK45", rtol=self.rtol, atol=self.atol,
                            events=ev_funcs or None, dense_output=True)
            if sol.status < 0:
                raise RuntimeError(f"solve_ivp failed at t = {t:.6f} s: {sol.message}")
            n_rhs += int(sol.nfev)
            n_seg += 1
            t_new = float(sol.t[-1])
            # samples in [t, t_new); t_new itself belongs to the next segment (the state is
            # continuous there), except at the very end
            io_end = n_out if t_new >= t_total else int(np.searchsorted(t_out, t_new, side="left"))
            if io_end > io:
                xv[:, io:io_end] = sol.sol(t_out[io:io_end])[:2]
                io = io_end
            y = sol.y[:, -1].copy()
            fired = ""
            if sol.status == 1:
                fired = next(f.__name__ for f, te in zip(ev_funcs, sol.t_events, strict=True)
                             if te.size)
            if md.gslip and slip is not None:
                slip.extend_trough(self._extreme_force(sol, xs_t, vs, t, md.sign), md.sign)
                if fired:
                    events.append(self._end_slip(md, y, fn, slip, t_new, len(events)))
                    slip = None
            elif fired and self._switch(md, y, fn, fired):
                xs_e = xs_t + vs * (t_new - t)
                peak = p.k0_N_per_m * (xs_e - y[0]) + p.c0_N_s_per_m * (vs - y[1])
                slip = _SlipRecord(t_new, float(y[0]), float(peak), float(peak))
            stalls = stalls + 1 if t_new <= t else 0
            if stalls > 4 * n + 8:
                raise RuntimeError(f"RK45 reference: events without progress at t = {t:.9f} s")
            t = t_new
        wall_s = time.perf_counter() - wall0
        xs_out = np.interp(t_out, drive.t_s, drive.x_stage_m)
        seg = np.clip(np.searchsorted(drive.t_s, t_out, side="right") - 1, 0, drive.t_s.size - 2)
        vs_out = (np.diff(drive.x_stage_m) / np.diff(drive.t_s))[seg]
        ft = p.k0_N_per_m * (xs_out - xv[0]) + p.c0_N_s_per_m * (vs_out - xv[1])
        return RefResult(t_s=t_out, ft_N=ft, x_specimen_m=xv[0], v_specimen_m_s=xv[1],
                         events=events, n_rhs=n_rhs, n_segments=n_seg, wall_s=wall_s)

    # --- mode changes ------------------------------------------------------------------------------
    def _switch(self, md: _Modes, y: np.ndarray, fn: float, which: str) -> bool:
        """Apply a stick-phase event (in place); return True when a global slip starts."""
        p = self.p
        kt = p.kt(md.stage)
        thr = p.mu_static(md.stage) * fn * p.shares(md.stage)
        x = y[0]
        if which == "threshold":
            f = kt * (x - y[2:])
            stuck = md.mode == 0
            fwd = stuck & (f >= thr - kt * _X_TOL_M)
            back = stuck & (f <= -thr + kt * _X_TOL_M)
            if not (fwd.any() or back.any()):  # the located root is a hair short: take the nearest
                i = int(np.flatnonzero(stuck)[np.argmin(thr[stuck] - np.abs(f[stuck]))])
                (fwd if f[i] >= 0 else back)[i] = True
            md.mode[fwd] = 1
            md.mode[back] = -1
            moving = md.mode != 0
            y[2:][moving] = x - md.mode[moving] * thr[moving] / kt  # exactly at the threshold
        else:  # a velocity reversal: presliding elements of that direction stick at their force
            md.mode[md.mode == (1 if which == "fwd_reversal" else -1)] = 0
        if np.any(md.mode == 0):
            return False
        md.sign = 1 if int(md.mode.sum()) >= 0 else -1
        md.gslip = True
        md.stage = 1  # the first global slip ends the initial stage (paper Sec. 3.1)
        md.mode[:] = md.sign
        return True

    def _end_slip(self, md: _Modes, y: np.ndarray, fn: float, slip: _SlipRecord, t_end: float,
                  n_before: int) -> RefEvent:
        """V = 0: every element sticks (in place), keeping the kinetic force mu_k Fn / N."""
        p = self.p
        y[2:] = y[0] - md.sign * p.mu_k * fn * p.shares(1) / p.kt(1)
        md.gslip = False
        md.mode[:] = 0
        return RefEvent(t_start_s=slip.t_start_s, t_end_s=t_end, peak_N=slip.peak_N,
                        trough_N=slip.trough_N, slip_m=float(y[0] - slip.x_start_m),
                        stage="initial" if n_before == 0 else "stable")

    def _extreme_force(self, sol: Any, xs0: float, vs: float, t0: float, sign: int) -> float:
        """Lowest (forward slip) or highest drive force over a slip segment (dense output)."""
        p = self.p
        ts = np.linspace(sol.t[0], sol.t[-1], 257)
        ys = sol.sol(ts)
        fd = p.k0_N_per_m * (xs0 + vs * (ts - t0) - ys[0]) + p.c0_N_s_per_m * (vs - ys[1])
        return float(fd.min() if sign > 0 else fd.max())


@dataclass
class _SlipRecord:
    """A running global slip."""

    t_start_s: float
    x_start_m: float
    peak_N: float
    trough_N: float

    def extend_trough(self, value_N: float, sign: int) -> None:
        self.trough_N = min(self.trough_N, value_N) if sign > 0 else max(self.trough_N, value_N)
