"""An effect added to a model of another rig has its fixed dimensional parameters (reference load,
reference velocity, contact age) at the data's scale (search_space.effects_at_data_scale), in the
search and in the screen alike: no coordinate moves them, so at the preset's scale they would be
wrong by the scale ratio. The screen and the search also evaluate each added effect at its typical
size (search_space.typical_point)."""

from __future__ import annotations

import math

import pytest

from rigctl.model import Drive, Simulator, build_model
from rigctl.model.noise import NoiseModel
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench.budget import Budget
from rigctl.workbench.data_start import campaign_scale
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice, with_effects
from rigctl.workbench.screening import score_screen
from rigctl.workbench.search import search_model
from rigctl.workbench.search_space import effects_at_data_scale, typical_point
from tests.workbench.synth import ANOTHER_RIG, ANOTHER_RIG_FN_N, another_rig_record

EFFECTS = ("load_dependent_friction", "rate_state")


def _records(**metadata: float) -> Dataset:
    run = another_rig_record(12.0)
    run.metadata.update({f"rig.{k}": str(v) for k, v in metadata.items()})
    return prepare_dataset([run])


@pytest.fixture(scope="module")
def dataset() -> Dataset:
    return _records()


def _value(choice: ModelChoice, name: str) -> float:
    return next(p.value for p in choice.parameter_table() if p.name == name)


def _model() -> ModelChoice:
    return with_effects(ModelChoice("paper").with_values(dict(ANOTHER_RIG)), EFFECTS)


def test_fixed_reference_values_move_to_the_campaigns_scale(dataset):
    before = _model()
    after = effects_at_data_scale(dataset, before, EFFECTS)
    v = after.values
    # the preset's reference load is 300 N; this campaign runs at 10 N
    assert _value(before, "load_dependent_friction.fn_ref_N") == pytest.approx(300.0)
    assert v["load_dependent_friction.fn_ref_N"] == pytest.approx(ANOTHER_RIG_FN_N, rel=0.2)
    # the reference velocity follows the drive's velocity (another rig drives far slower or
    # faster than the preset's 10 um/s)
    drive = float(dataset.runs[0].events.covariates["v_drive_m_per_s"][0])
    ratio = v["rate_state.v_ref_m_per_s"] / abs(drive)
    assert 0.1 < ratio < 10.0
    # identified parameters are the search's to move: their values are not touched
    for name in ("load_dependent_friction.alpha_s", "rate_state.a", "rate_state.dc_m"):
        assert name not in v
        assert _value(after, name) == _value(before, name)


def test_only_the_named_effects_and_not_what_the_rig_fixes(dataset):
    before = _model()
    only_one = effects_at_data_scale(dataset, before, ("rate_state",))
    assert "load_dependent_friction.fn_ref_N" not in only_one.values
    fixed = _records(**{"load_dependent_friction.fn_ref_N": 25.0})
    stated = effects_at_data_scale(fixed, before, EFFECTS)
    assert "load_dependent_friction.fn_ref_N" not in stated.values


def test_a_small_exponent_at_the_data_scale_leaves_the_levels_where_the_base_put_them(dataset):
    """The reason for the rule: with the reference at the campaign's load, a load exponent bends
    the friction levels around the base's, and the error moves a little; with the preset's 300 N
    it rescales both levels by (10/300)^alpha and the error explodes."""
    base = ModelChoice("paper").with_values(dict(ANOTHER_RIG))
    e_base = evaluate(dataset, base).score.error
    on = {"load_dependent_friction.alpha_s": 0.1, "load_dependent_friction.alpha_k": 0.1}
    preset = with_effects(base, ("load_dependent_friction",)).with_values(on)
    scaled = effects_at_data_scale(dataset, with_effects(base, ("load_dependent_friction",)),
                                   ("load_dependent_friction",)).with_values(on)
    e_scaled = evaluate(dataset, scaled).score.error
    e_preset = evaluate(dataset, preset).score.error
    assert math.isfinite(e_scaled)
    assert e_scaled < 2.0 * e_base + 1.0
    assert e_preset > 3.0 * e_scaled


def test_the_search_fits_an_added_effect_with_its_reference_at_the_data_scale(dataset):
    base = ModelChoice("paper").with_values(dict(ANOTHER_RIG))
    fit = search_model(dataset, with_effects(base, ("load_dependent_friction",)),
                       budget=Budget(max_evaluations=30), workers=0, with_uncertainty=False)
    assert _value(fit.choice, "load_dependent_friction.fn_ref_N") == \
        pytest.approx(ANOTHER_RIG_FN_N, rel=0.2)


def test_the_typical_point_is_the_library_size_at_the_data_scale(dataset):
    fitted = _model().with_values({"load_dependent_friction.alpha_s": -0.7, "mu_s": 0.41})
    typical = typical_point(dataset, fitted, ("load_dependent_friction",))
    assert typical is not None
    assert _value(typical, "load_dependent_friction.alpha_s") == pytest.approx(0.3)  # library
    assert _value(typical, "load_dependent_friction.fn_ref_N") == \
        pytest.approx(ANOTHER_RIG_FN_N, rel=0.2)
    assert typical.values["mu_s"] == 0.41  # the model it is added to, as it is
    assert typical_point(dataset, fitted, ()) is None


def _sweep(model: object, loads_N: tuple[float, ...]) -> Dataset:
    keff = 1.0 / (1.0 / ANOTHER_RIG["k0_N_per_m"] + 1.0 / ANOTHER_RIG["kts_N_per_m"])
    v = 2.0 * (ANOTHER_RIG["mu_s"] - ANOTHER_RIG["mu_k"]) * ANOTHER_RIG_FN_N / keff / 0.5
    runs = []
    for k, fn in enumerate(loads_N):
        res = Simulator(model, sample_rate_hz=500.0).run(  # type: ignore[arg-type]
            Drive.constant(fn, v, 6.0), noise=NoiseModel(ft_rms_N=0.01, fn_rms_N=0.01),
            seed=k + 1, record_elements=False)
        run = res.to_measured()
        run.source = f"sweep_{fn:g}N"
        runs.append(run)
    return prepare_dataset(runs)


def test_the_screen_sees_an_effect_at_its_typical_size():
    """Load exponents on both friction levels at the library's size: the friction fits every load
    only where the two exponents are near each other, a narrow diagonal of their plane that the
    screen's scattered points can miss, while the typical-size point lies on it."""
    # the law referred to the campaign's own load scale, the median load of its slips (the
    # lightest run slips most often): where the data-scale rule puts the reference
    on = {"alpha_s": 0.3, "alpha_k": 0.3, "fn_ref_N": 6.0}
    truth = build_model("paper", effects=["load_dependent_friction"], params=dict(ANOTHER_RIG),
                        effect_params={"load_dependent_friction": on})
    data = _sweep(truth, (6.0, 10.0, 16.0))
    assert campaign_scale(data).fn_N == pytest.approx(6.0, rel=0.05)
    base = ModelChoice("paper").with_values(dict(ANOTHER_RIG))
    e_base = evaluate(data, base).score.error
    model = FitResult(base, e_base, {}, ())
    (s,) = score_screen(data, model, [("load_dependent_friction",)], workers=0)
    assert s.best_at.startswith("typical size"), s  # as drawn, or with the levels re-read
    assert s.error < 0.5 * e_base, (s, e_base)
