"""``EffectContract``: the rules of :class:`rigctl.model.Effect` as tests, for any effect.

Mix it into a test class and name the effect; pytest (or unittest, with ``unittest.TestCase`` as a
second base) then runs every ``test_*`` method below against it::

    from rigctl.testing import EffectContract
    from my_lab.effects import ThermalCreep

    class TestThermalCreep(EffectContract):
        effect = ThermalCreep

Each test simulates a short drive that exercises every code path of the engine (slides at 0.1 mm/s
with slips in both directions, a hold, normal-force steps, a reversal): 7 s at 1024 Hz, a few
milliseconds to a second per run. Override :meth:`contract_drive` for another drive, ``base``
for another base model (an effect that is part of ``paper``, such as ``stress_evolution``, is
tested against ``classic``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from rigctl.model import Drive, Effect, ModelSpec, ParameterError, SimResult, Simulator, build_model
from rigctl.model.params import BASE_PARAMS, check_values
from rigctl.model.plugins import validate_effect_class
from rigctl.model.spec import BASES

CHANNELS = ("t_s", "x_stage_m", "fn_N", "ft_N", "f_interface_N", "x_specimen_m",
            "v_specimen_m_s", "delta_m", "d1_m", "d2_m", "stage", "slipping", "element_mode")
"""Every per-sample output of :class:`~rigctl.model.SimResult`."""

BOUND_NUDGE = 1e-6  # relative step beyond a bound that must be refused (well above round-off)


def _differences(a: SimResult, b: SimResult) -> list[str]:
    """Names of the outputs (channels, events) in which two results are not bit-identical."""
    out = [c for c in CHANNELS if not np.array_equal(getattr(a, c), getattr(b, c))]
    if a.events != b.events:
        out.append("events")
    return out


class EffectContract:
    """Tests every effect must pass: declaration, off-reduction, bounds, validity, determinism.

    Set ``effect`` to the class under test; optionally ``base`` (the base model it is added to,
    ``"paper"`` unless the effect is part of it) and ``rate_hz``.
    """

    effect: ClassVar[type[Effect]]
    base: ClassVar[str] = "paper"
    rate_hz: ClassVar[float] = 1024.0

    # --- helpers (override contract_drive to test on another drive) ---------------------------
    def contract_drive(self) -> Drive:
        """Slides, a hold, a normal-force change, a reversal with a rising Fn: every code path."""
        v = 1e-4
        t = np.array([0.0, 2.5, 3.0, 3.5, 4.5, 7.0])
        x = v * np.array([0.0, 2.5, 2.5, 2.5, 1.5, -1.0])
        fn = np.array([300.0, 300.0, 300.0, 260.0, 260.0, 330.0])
        return Drive(t, x, fn)

    def _base_values(self) -> dict[str, float]:
        return check_values(BASE_PARAMS, {}, "base")

    def _model(self, values: Mapping[str, float] | None = None) -> ModelSpec:
        name = self.effect.name
        if name in BASES.get(self.base, ()):
            raise AssertionError(
                f"effect '{name}' is part of the base '{self.base}': set `base` to one without it"
            )
        params = {name: dict(values)} if values is not None else None
        return build_model(self.base, effects=[self.effect], effect_params=params)

    def _run(self, model: ModelSpec, **kwargs: Any) -> SimResult:
        return Simulator(model, self.rate_hz).run(self.contract_drive(), **kwargs)

    def _fn_range(self) -> tuple[float, float]:
        fn = self.contract_drive().fn_N
        return float(fn.min()), float(fn.max())

    # --- rule 1: declaration ------------------------------------------------------------------
    def test_declaration_is_complete(self) -> None:
        cls = self.effect
        validate_effect_class(cls, f"{cls.__module__}.{cls.__qualname__}")
        assert cls.summary and cls.signature and cls.reveal_protocol, (
            "summary, signature and reveal_protocol say what the effect is and how to see it")
        assert cls.params, "an effect without parameters can be neither fitted nor switched off"

    # --- rule 2: off values and defaults ------------------------------------------------------
    def test_off_and_default_values_lie_within_the_bounds(self) -> None:
        eff = self.effect()
        base = self._base_values()
        off = eff.off_values(base)
        default = eff.default_values(base)
        assert set(off) == set(default) == {p.name for p in eff.params}
        for p in eff.params:
            assert p.lower <= off[p.name] <= p.upper, f"off value of {p.name} outside its bounds"
            assert p.lower <= default[p.name] <= p.upper, f"default of {p.name} outside bounds"
        assert off != default, "at its defaults the effect must differ from off"

    def test_off_values_reduce_the_model_exactly_to_the_base(self) -> None:
        eff = self.effect()
        at_off = self._run(self._model(eff.off_values(self._base_values())))
        without = self._run(build_model(self.base))
        assert len(without.events) >= 2, "the contract drive must produce slips"
        differ = _differences(at_off, without)
        assert not differ, f"'{eff.name}' at its off values changes {', '.join(differ)}"

    def test_default_values_change_the_model(self) -> None:
        at_default = self._run(self._model())
        without = self._run(build_model(self.base))
        assert _differences(at_default, without), (
            f"'{self.effect.name}' at its defaults leaves every output unchanged")

    # --- bounds ----------------------------------------------------------------------------------
    def test_every_parameter_runs_at_its_bounds_and_is_refused_beyond(self) -> None:
        eff = self.effect()
        base = self._base_values()
        default = eff.default_values(base)
        for p in eff.params:
            for bound, outward in ((p.lower, -1.0), (p.upper, 1.0)):
                values = {**default, p.name: bound}
                model = self._model(values)
                reason = model.invalid_reason(self._fn_range())
                if reason is None:
                    res = self._run(model)
                    for c in ("ft_N", "fn_N", "f_interface_N", "x_specimen_m", "d1_m", "d2_m"):
                        assert np.all(np.isfinite(getattr(res, c))), (
                            f"{p.name} = {bound:g}: non-finite {c}")
                beyond = bound + outward * max(abs(bound) * BOUND_NUDGE, BOUND_NUDGE)
                if p.integer:
                    beyond = bound + outward
                try:
                    self._model({**default, p.name: beyond})
                except ParameterError as exc:
                    assert p.name in str(exc), f"the error must name {p.name}: {exc}"
                else:
                    raise AssertionError(f"{p.name} = {beyond:g} beyond its bound is accepted")

    # --- rule 6: validity -------------------------------------------------------------------
    def test_default_values_are_physically_valid(self) -> None:
        eff = self.effect()
        base = self._base_values()
        reason = eff.invalid_reason(eff.default_values(base), base)
        assert reason is None, f"defaults declared invalid: {reason}"
        assert self._model().invalid_reason(self._fn_range()) is None
        off_reason = eff.invalid_reason(eff.off_values(base), base)
        assert off_reason is None, f"off values declared invalid: {off_reason}"

    # --- rules 4 and 5: determinism, no state on the instance -------------------------------------
    def test_runs_are_deterministic_and_keep_no_state_on_the_instance(self) -> None:
        model = self._model()
        first = self._run(model, noise=True, seed=7)
        again = self._run(model, noise=True, seed=7)  # same effect instance, a second run
        rebuilt = self._run(self._model(), noise=True, seed=7)  # a fresh instance
        assert not _differences(first, again), "two runs of one model differ"
        assert not _differences(first, rebuilt), "a rebuilt model gives another result"
        assert math.isfinite(float(first.ft_N.sum()))
