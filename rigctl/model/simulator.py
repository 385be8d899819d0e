"""Run the model: whole histories (:meth:`Simulator.run`) or step by step (:class:`Stepper`).

Both drive the compiled kernel (:mod:`rigctl.model.kernel`) over piecewise-linear inputs, call the
effects' slip hooks after every global slip, apply output hooks, and return :class:`SimResult`.
Same inputs, parameters and seed give bit-identical output.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rigctl.errors import SimulationError
from rigctl.model import layout
from rigctl.model.drive import Drive, check_fn
from rigctl.model.effects import CoreParams, SlipContext
from rigctl.model.kernel import advance, state_sample
from rigctl.model.kernel.general import advance_terms
from rigctl.model.noise import NoiseModel
from rigctl.model.params import ParameterError
from rigctl.model.result import SimResult, SlipEvent
from rigctl.model.spec import CoreSetup, ModelSpec
from rigctl.model.terms import PluginTermError, first_class_functions

STATED_RIG_PARAMS = ("m_kg", "c0_N_s_per_m")
"""Parameters a simulated run states in its metadata (:func:`stated_rig_parameters`): a rig
knows its moving mass and drive damping; the data of another rig, which does not state them, leave
them to the fit."""


def stated_rig_parameters(model: ModelSpec) -> dict[str, str]:
    """What a simulated rig states about itself, as a lab states what it knows of its rig
    (``rig.<parameter>`` metadata, docs/csv-format.md): its moving mass and drive damping. The
    workbench fits these where a record does not state them (another lab's data)."""
    values = model.values()
    return {f"rig.{name}": f"{values[name]!r}" for name in STATED_RIG_PARAMS if name in values}

SimProgressFn = Callable[[float, float], None]
"""progress(t_done_s, t_total_s)"""


class SlipBudgetError(SimulationError):
    """The model slipped more often than the run's ``max_slips`` allows."""


class TimeLimitError(SimulationError):
    """The run passed its ``deadline`` (:func:`run_clock`) before it ended."""


def run_clock() -> float:
    """The clock a run's ``deadline`` is read on: CPU seconds of the calling thread
    (:func:`time.thread_time`; the engine runs in it). A run is stopped for the work it has done,
    not for the time other processes took from it: on a machine shared with other jobs a wall
    clock would stop runs that a quiet machine lets end, and so make a fit depend on the load."""
    return time.thread_time()


class Outputs(NamedTuple):
    """What the kernel writes per sample: the output table, the flag table, the element modes."""

    table: np.ndarray
    """float64, rows ``layout.O_*``, one column per sample"""
    flags: np.ndarray
    """uint8, rows ``layout.F_*``, one column per sample"""
    elements: np.ndarray
    """int8, one row per sample (one row in all when not recorded), one column per element"""


class _Integration:
    """Integrator state (kernel arrays) and the glue that calls hooks between kernel calls."""

    def __init__(self, setup: CoreSetup, x_stage0_m: float, fn0_N: float) -> None:
        self.setup = setup
        self.cp = setup.cp.copy()
        self.cp[layout.P_XPAR] = x_stage0_m  # parallel springs are relaxed where the slider starts
        self.core = CoreParams(self.cp)
        n = setup.weights.shape[1]
        self.n = n
        self.fs = np.zeros(layout.N_FSTATE)
        self.ist = np.zeros(layout.N_ISTATE, dtype=np.int64)
        self.fs[layout.S_X] = x_stage0_m
        self.fs[layout.S_X_INIT] = x_stage0_m
        self.fs[layout.S_THETA] = setup.theta0_s
        self.fs[layout.S_XS] = x_stage0_m
        self.fs[layout.S_FN] = fn0_N
        self.ist[layout.I_SIGN] = 1
        from rigctl.model.friction_laws import element_stiffness

        k = element_stiffness(self.cp, 0, fn0_N, n)
        self.fs[layout.S_K_USED] = k
        self.g = np.full(n, -k * x_stage0_m)  # all elements stuck, unloaded
        self.mode = np.zeros(n, dtype=np.int8)
        self.ev = np.full((64, layout.N_ECOLS), np.nan)
        self.events: list[SlipEvent] = []
        self.stage_names = ("initial", "stable")
        # plug-in terms (general path): their bundle, each element's stick start, their state
        self.terms = setup.terms.bundle() if setup.terms.active else None
        self.tstick = np.zeros(n)
        self.z = setup.terms.z0.copy()

    def integrate(
        self,
        kt_t: np.ndarray,
        kt_xs: np.ndarray,
        kt_fn: np.ndarray,
        t_out: np.ndarray,
        record_elements: bool,
        progress: SimProgressFn | None = None,
        max_slips: int | None = None,
        deadline: float | None = None,
    ) -> Outputs:
        """Integrate over the knots, sampling at ``t_out``; with ``max_slips``, stop with a
        SlipBudgetError if more than that many global slips are recorded (checked whenever the
        event table fills and at the end, so at most about twice that many are integrated); with
        ``deadline`` (a :func:`run_clock` value), stop with a TimeLimitError once the clock
        passes it (checked whenever the kernel returns: after each 1 % of the span, each slip
        whose hooks run and each growth of the event table)."""
        n_out = t_out.shape[0]
        knots = np.empty((layout.N_KROWS, kt_t.shape[0]))
        knots[layout.K_T] = kt_t
        knots[layout.K_XS] = kt_xs
        knots[layout.K_FN] = kt_fn
        out = Outputs(
            np.empty((layout.N_OROWS, n_out)),
            np.empty((layout.N_FROWS, n_out), dtype=np.uint8),
            np.zeros((n_out if record_elements else 1, self.n), dtype=np.int8),
        )
        self.ist[layout.I_KNOT] = 0
        self.ist[layout.I_OUT] = 0
        t_end = float(kt_t[-1])
        hooks = self.setup.slip_hooks
        # progress is reported at chunk boundaries of about 1 % of the span
        chunk = max((t_end - self.fs[layout.S_T]) / 100.0, 1e-3) \
            if progress or deadline is not None else np.inf
        while True:
            t_stop = min(t_end, self.fs[layout.S_T] + chunk)
            if self.terms is None:
                code = advance(
                    self.cp, self.setup.weights, self.fs, self.ist, self.g, self.mode,
                    knots, t_out, out.table, out.flags, out.elements, self.ev,
                    t_stop, bool(hooks), record_elements,
                )
            else:
                code = self._advance_terms(knots, t_out, out, t_stop, bool(hooks),
                                           record_elements)
            if deadline is not None and run_clock() > deadline:
                raise TimeLimitError(
                    f"the run passed its time limit at t = {self.fs[layout.S_T]:.6g} s "
                    f"({int(self.ist[layout.I_NEVENT])} global slips)")
            if code == layout.RET_EVENT_TABLE_FULL:
                self._check_slips(max_slips)
                grown = np.full((self.ev.shape[0] * 2, layout.N_ECOLS), np.nan)
                grown[: self.ev.shape[0]] = self.ev
                self.ev = grown
            elif code == layout.RET_SLIP_END:
                self._run_hooks()
            else:
                if progress is not None:
                    progress(float(self.fs[layout.S_T]), t_end)
                if t_stop >= t_end:
                    break
        self._check_slips(max_slips)
        if self.ist[layout.I_OUT] < n_out:
            raise RuntimeError(
                f"integration stopped at t = {self.fs[layout.S_T]:.9g} s before output sample "
                f"{int(self.ist[layout.I_OUT])} at {t_out[self.ist[layout.I_OUT]]:.9g} s"
            )
        return out

    def _advance_terms(self, knots: np.ndarray, t_out: np.ndarray, out: Outputs, t_stop: float,
                       stop_on_slip_end: bool, record_elements: bool) -> int:
        """The general path (plug-in terms); a term that raises or is not finite ends the run
        with one :class:`PluginTermError` naming the plug-in and the state."""
        try:
            with first_class_functions():  # numba's experimental-feature warning, safe here
                code = int(advance_terms(
                    self.cp, self.setup.weights, self.terms, self.fs, self.ist, self.g, self.mode,
                    self.tstick, self.z, knots, t_out, out.table, out.flags, out.elements,
                    self.ev, t_stop, stop_on_slip_end, record_elements,
                ))
            if code != layout.RET_TERM_ERROR:
                return code
            why = "made the state non-finite"
        except Exception as exc:  # whatever a plug-in's compiled code raised
            why = f"raised {type(exc).__name__}: {exc}"
        fs = self.fs
        t, x, v = (float(fs[layout.S_T]), float(fs[layout.S_X]), float(fs[layout.S_V]))
        j = int(self.ist[layout.I_KNOT])
        fn = float(knots[layout.K_FN, min(j, knots.shape[1] - 1)])
        culprit = self.setup.terms.culprit(t, x, v, fn, float(self.cp[layout.P_MUS]), self.z,
                                           why)
        raise PluginTermError(
            f"{culprit} at t = {t:.6g} s, X = {x:.6g} m, V = {v:.6g} m/s, Fn = {fn:.6g} N")

    def _check_slips(self, max_slips: int | None) -> None:
        n_ev = int(self.ist[layout.I_NEVENT])
        if max_slips is not None and n_ev > max_slips:
            raise SlipBudgetError(f"more than {max_slips} global slips by t = "
                                     f"{self.fs[layout.S_T]:.6g} s ({n_ev} recorded)")

    def _run_hooks(self) -> None:
        i_ev = int(self.ist[layout.I_NEVENT]) - 1
        row = self.ev[i_ev]
        stick_from = float(self.ev[i_ev - 1, layout.E_T_END]) if i_ev > 0 else 0.0
        ctx = SlipContext(
            t_s=float(row[layout.E_T_END]),
            n_slips=int(self.ist[layout.I_NSLIP]),
            slip_m=float(row[layout.E_SLIP]),
            cumulative_slip_m=float(self.fs[layout.S_SLIP_CUM]),
            fn_N=float(row[layout.E_FN]),
            peak_N=float(row[layout.E_PEAK]),
            trough_N=float(row[layout.E_TROUGH]),
            x_start_m=float(row[layout.E_X_START]),
            x_end_m=float(row[layout.E_X_START] + row[layout.E_SLIP]),
            peak_velocity_m_s=float(row[layout.E_V_PEAK]),
            stick_s=float(row[layout.E_T_START]) - stick_from,
        )
        for entry in self.setup.slip_hooks:
            entry.effect.on_slip_end(self.core, entry.values, ctx)

    def take_events(self, t_first: float, t_last: float) -> list[SlipEvent]:
        """Completed events so far not yet returned (by count)."""
        n_done = int(self.ist[layout.I_NEVENT])
        new = []
        for i in range(len(self.events), n_done):
            r = self.ev[i]
            new.append(
                SlipEvent(
                    t_start_s=float(r[layout.E_T_START]),
                    t_end_s=float(r[layout.E_T_END]),
                    peak_N=float(r[layout.E_PEAK]),
                    trough_N=float(r[layout.E_TROUGH]),
                    slip_m=float(r[layout.E_SLIP]),
                    stage=self.stage_names[int(r[layout.E_STAGE])],
                    fn_N=float(r[layout.E_FN]),
                )
            )
        self.events.extend(new)
        return new

    def result(
        self, out: Outputs, t_out: np.ndarray, new_events: list[SlipEvent],
        record_elements: bool,
    ) -> SimResult:
        tab = out.table
        x = tab[layout.O_X]
        delta = x - self.fs[layout.S_X_INIT]
        elem = out.elements if record_elements else np.zeros((t_out.shape[0], self.n), np.int8)
        res = SimResult(
            t_s=t_out.copy(), x_stage_m=tab[layout.O_XS], fn_N=tab[layout.O_FN],
            ft_N=tab[layout.O_FT], f_interface_N=tab[layout.O_FI], x_specimen_m=x,
            v_specimen_m_s=tab[layout.O_V], delta_m=delta, d1_m=delta.copy(),
            d2_m=np.zeros_like(delta), stage=out.flags[layout.F_STAGE],
            slipping=out.flags[layout.F_SLIP].view(np.bool_), element_mode=elem,
            p_tables=self.setup.p_tables, events=new_events,
        )
        for entry in self.setup.output_hooks:
            entry.effect.transform_output(res, entry.values)
        chatter = int(self.ist[layout.I_CHATTER])
        if chatter:
            res.metadata["warning"] = (
                f"event budget exhausted in {chatter} sample interval(s): threshold chattering "
                "near zero load was integrated without events there"
            )
        return res


@dataclass(frozen=True)
class StepperState:
    """Instantaneous state of a stepper (SI units)."""

    t_s: float
    x_stage_m: float
    fn_N: float
    ft_N: float
    f_interface_N: float
    delta_m: float
    x_specimen_m: float
    v_specimen_m_s: float
    stage: int
    p_elements: np.ndarray
    sliding_elements: np.ndarray
    n_slips: int


class Simulator:
    """The stick-slip model of the rig at the sensor sample rate."""

    def __init__(self, model: ModelSpec, sample_rate_hz: float = 1024.0) -> None:
        if not np.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
            raise ParameterError(f"sample rate must be positive, got {sample_rate_hz}")
        self.model = model
        self.sample_rate_hz = float(sample_rate_hz)
        self._setup = model.core_setup()

    def run(
        self,
        drive: Drive,
        *,
        noise: bool | NoiseModel = False,
        seed: int | None = None,
        record_elements: bool = True,
        progress: SimProgressFn | None = None,
        max_slips: int | None = None,
        deadline: float | None = None,
    ) -> SimResult:
        """Simulate the whole drive; samples at k / rate for k = 0 .. duration * rate.

        ``max_slips`` bounds the work of a model that slips far more often than anything it is
        compared with (:class:`SlipBudgetError`), ``deadline`` (a :func:`run_clock` value)
        its CPU time (:class:`TimeLimitError`), see :meth:`_Integration.integrate`."""
        n_out = int(np.floor(drive.duration_s * self.sample_rate_hz + 1e-9)) + 1
        t_out = np.arange(n_out, dtype=np.float64) / self.sample_rate_hz
        integ = _Integration(self._setup, float(drive.x_stage_m[0]), float(drive.fn_N[0]))
        kt_t = drive.t_s
        if t_out[-1] > kt_t[-1]:
            # the last sample lies within 1e-9 s past the drive's end (rounding of the duration):
            # end the last input segment exactly on it
            kt_t = kt_t.copy()
            kt_t[-1] = t_out[-1]
        out = integ.integrate(kt_t, drive.x_stage_m, drive.fn_N, t_out, record_elements,
                              progress, max_slips, deadline)
        res = integ.result(out, t_out, integ.take_events(0.0, drive.duration_s), record_elements)
        res.metadata.update(
            {"model": self.model.describe(), "sample_rate_hz": f"{self.sample_rate_hz:g}"}
        )
        res.metadata.update(stated_rig_parameters(self.model))
        if noise:
            model = noise if isinstance(noise, NoiseModel) else NoiseModel()
            model.apply(res, np.random.default_rng(seed))
            res.metadata["noise"] = model.describe()
            res.metadata["seed"] = str(seed)
        return res

    def stepper(self, x_stage_m: float = 0.0, fn_N: float = 0.0) -> Stepper:
        return Stepper(self, x_stage_m, fn_N)


class Stepper:
    """Advance the model piece by piece, e.g. under a virtual rig's clock."""

    def __init__(self, sim: Simulator, x_stage_m: float, fn_N: float) -> None:
        self._sim = sim
        self._integ = _Integration(sim._setup, float(x_stage_m), check_fn(fn_N))
        self._next_k = 0
        self._xs = float(x_stage_m)
        self._fn = float(fn_N)

    @property
    def t_s(self) -> float:
        return float(self._integ.fs[layout.S_T])

    def advance(self, t_end_s: float, x_stage_end_m: float, fn_end_N: float) -> SimResult:
        """Ramp the inputs linearly to the given end values over (t_now, t_end]; return samples."""
        t0 = self.t_s
        t1 = float(t_end_s)
        x1 = float(x_stage_end_m)
        f1 = check_fn(fn_end_N)
        if not np.isfinite(t1) or not np.isfinite(x1):
            raise ParameterError("stepper inputs must be finite")
        if t1 < t0:
            raise ParameterError(f"cannot step back in time ({t1} s < {t0} s)")
        rate = self._sim.sample_rate_hz
        k_last = int(np.floor(t1 * rate + 1e-9))
        if k_last / rate > t1:
            t1 = k_last / rate  # within 1e-9 of a sample time: end exactly on it
        ks = np.arange(self._next_k, k_last + 1)
        t_out = ks / rate
        if t1 == t0:
            kt_t = np.array([t0, t0 + 1e-12])
            kt_x = np.array([self._xs, x1])
            kt_f = np.array([self._fn, f1])
            t_stop_knots = (kt_t, kt_x, kt_f)
        else:
            t_stop_knots = (np.array([t0, t1]), np.array([self._xs, x1]), np.array([self._fn, f1]))
        out = self._integ.integrate(*t_stop_knots, t_out, True)
        self._next_k = k_last + 1
        self._xs, self._fn = x1, f1
        return self._integ.result(out, t_out, self._integ.take_events(t0, t1), True)

    @property
    def state(self) -> StepperState:
        integ = self._integ
        tab = np.empty((layout.N_OROWS, 1))
        flags = np.empty((layout.N_FROWS, 1), dtype=np.uint8)
        el = np.empty((1, integ.n), dtype=np.int8)
        state_sample(
            integ.cp, integ.setup.weights, integ.fs, integ.ist, integ.g, integ.mode,
            self._xs, self._fn, tab, flags, el,
        )
        stage = int(integ.ist[layout.I_STAGE])
        return StepperState(
            t_s=self.t_s, x_stage_m=self._xs, fn_N=float(tab[layout.O_FN, 0]),
            ft_N=float(tab[layout.O_FT, 0]), f_interface_N=float(tab[layout.O_FI, 0]),
            delta_m=float(integ.fs[layout.S_X] - integ.fs[layout.S_X_INIT]),
            x_specimen_m=float(integ.fs[layout.S_X]), v_specimen_m_s=float(integ.fs[layout.S_V]),
            stage=stage, p_elements=integ.setup.p_tables[stage].copy(),
            sliding_elements=el[0] != 0, n_slips=int(integ.ist[layout.I_NSLIP]),
        )
