"""User effects: plug-in files, entry points, their validation, and the worked example of docs/effects.md."""

from __future__ import annotations

import shutil
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rigctl.cli.main import main
from rigctl.io.csv_format import read_csv
from rigctl.model import Drive, Simulator, build_model
from rigctl.model.plugins import (
    ENABLE_ENV,
    ENTRY_POINT_GROUP,
    EffectPluginError,
    effect_registry,
    entry_point_effects,
    load_effect_file,
)

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "my_effect.py"
DRIVE = Drive.constant(300.0, 1e-4, 3.0)

HEADER = "from rigctl.model import Effect, ParamSpec\n"

GOOD_PLUGIN = HEADER + textwrap.dedent(
    '''
    class SoftStick(Effect):
        """mu_s scaled by (1 - r): a test effect. Off: r = 0."""

        name = "soft_stick"
        summary = "lower static friction"
        params = (ParamSpec("r", 0.2, 0.0, 0.9, "-", "relative reduction of mu_s", off=0.0),)

        def apply(self, core, values):
            core["mu_s"] = core["mu_s"] * (1.0 - values["r"])
    '''
)


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_file_plugin_loads_builds_and_changes_the_output(tmp_path):
    path = write(tmp_path, "soft.py", GOOD_PLUGIN)
    classes = load_effect_file(path)
    assert [c.name for c in classes] == ["soft_stick"]
    model = build_model("classic", effects=classes)
    assert model.effect_names == ["soft_stick"]
    res = Simulator(model).run(DRIVE)
    stable = [e for e in res.events if e.stage == "stable"]
    assert stable and all(e.peak_N == pytest.approx(0.15 * 0.8 * 300.0, rel=1e-3) for e in stable)
    # at its off value it is exactly the base; by name through a registry it takes overrides
    off = Simulator(build_model("classic", effects=classes,
                                effect_params={"soft_stick": {"r": 0.0}})).run(DRIVE)
    assert np.array_equal(off.ft_N, Simulator(build_model("classic")).run(DRIVE).ft_N)
    reg = effect_registry([path])
    spec = build_model("paper", effects=["soft_stick"], effect_params={"soft_stick": {"r": 0.5}},
                       registry=reg)
    assert spec.values()["soft_stick.r"] == 0.5


@pytest.mark.parametrize(
    ("text", "says"),
    [
        (HEADER + "class Broken(Effect:\n    pass\n", "SyntaxError"),
        ("import rigctl_no_such_module_xyz\n" + GOOD_PLUGIN, "ModuleNotFoundError"),
        ("x = 1\n", "no subclass"),
        (GOOD_PLUGIN.replace(', off=0.0)', ')'), "no `off`"),
        (GOOD_PLUGIN.replace('"soft_stick"', '"wear"'), "taken by the built-in library"),
        (GOOD_PLUGIN.replace('name = "soft_stick"', 'name = ""'), "needs a `name`"),
        (GOOD_PLUGIN.replace('off=0.0', 'off=2.0'), "outside its bounds"),
        (GOOD_PLUGIN.replace('"-", "relative', '"", "relative'), "no unit"),
        (GOOD_PLUGIN.replace("class SoftStick(Effect):",
                             "class SoftStick(Effect):\n    def __init__(self):\n"
                             "        raise RuntimeError('boom')\n"), "cannot instantiate"),
        (HEADER + "raise RuntimeError('at import')\n", "RuntimeError"),
    ],
    ids=["syntax", "import", "no-effect", "no-off", "name-clash", "no-name", "off-out-of-bounds",
         "no-unit", "constructor", "runtime-error"],
)
def test_broken_plugin_file_raises_naming_the_file(tmp_path, text, says):
    path = write(tmp_path, "broken_effect.py", text)
    with pytest.raises(EffectPluginError) as info:
        load_effect_file(path)
    msg = str(info.value)
    assert str(path) in msg and says in msg
    assert "\n" not in msg.strip()  # one line for the CLI


def test_missing_plugin_file_is_named(tmp_path):
    with pytest.raises(EffectPluginError, match=r"nope\.py: no such effect file"):
        load_effect_file(tmp_path / "nope.py")


def test_plugin_error_is_a_value_error_for_the_cli(tmp_path, capsys):
    """The CLI prints ValueError subclasses as one line and exits 2."""
    path = write(tmp_path, "broken_effect.py", "x = 1\n")
    assert main(["simulate", "--effect-file", str(path), "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken_effect.py" in err[0]


# --- the worked example of docs/effects.md ----------------------------------------------------

def test_worked_example_lowers_the_troughs_as_documented():
    (cls,) = load_effect_file(EXAMPLE)
    assert cls.name == "my_effect"
    base = Simulator(build_model("paper")).run(DRIVE)
    res = Simulator(build_model("paper", effects=[cls])).run(DRIVE)
    # defaults: c = -0.008 /K, T - T_ref = 10 K -> mu_k x 0.92: lower kinetic friction, deeper troughs
    tr0 = np.mean([e.trough_N for e in base.events if e.stage == "stable"])
    tr1 = np.mean([e.trough_N for e in res.events if e.stage == "stable"])
    assert tr1 < tr0 - 1.0
    # the stable peaks (mu_s) are untouched
    pk = [e.peak_N for e in res.events if e.stage == "stable"]
    assert np.allclose(pk, 0.15 * 300.0, rtol=1e-3)
    off = Simulator(build_model("paper", effects=[cls],
                                effect_params={"my_effect": cls().off_values({})})).run(DRIVE)
    assert np.array_equal(off.ft_N, base.ft_N)


def test_worked_example_refuses_a_non_physical_combination():
    (cls,) = load_effect_file(EXAMPLE)
    spec = build_model("paper", effects=[cls],
                       effect_params={"my_effect": {"c_per_K": -0.05, "temperature_K": 373.15}})
    with pytest.raises(ValueError, match="my_effect"):
        Simulator(spec)


def test_worked_example_from_the_cli(tmp_path, capsys):
    out = tmp_path / "run.csv"
    rc = main(["simulate", "--velocity", "1e-4", "--duration", "3", "--effect-file", str(EXAMPLE),
               "--effect", "my_effect:c_per_K=-0.01,temperature_K=313.15", "--out", str(out)])
    assert rc == 0
    assert "my_effect" in capsys.readouterr().out
    run = read_csv(out)
    base = Simulator(build_model("paper")).run(DRIVE)
    assert run.n_samples == base.n_samples
    assert run.ft_N.min() < base.ft_N.min() - 1.0  # mu_k x 0.8: deeper troughs
    assert main(["simulate", "--effect-file", str(EXAMPLE), "--effect", "my_effect:c_per_K=1"]) == 2
    assert "c_per_K" in capsys.readouterr().err


# --- entry points ------------------------------------------------------------------------------

@pytest.fixture
def installed_example(tmp_path, monkeypatch):
    """A package installed on sys.path whose dist-info registers the example as an entry point."""
    mod = "rigctl_test_effects_pkg"
    shutil.copy(EXAMPLE, tmp_path / f"{mod}.py")
    dist = tmp_path / "rigctl_test_effects_pkg-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: rigctl-test-effects-pkg\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        f"[{ENTRY_POINT_GROUP}]\nmy_effect = {mod}:ThermalKineticFriction\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv(ENABLE_ENV, "1")
    yield dist
    sys.modules.pop(mod, None)


def test_entry_points_are_not_loaded_unless_enabled(installed_example, monkeypatch, tmp_path,
                                                    capsys):
    monkeypatch.delenv(ENABLE_ENV)
    assert "my_effect" not in effect_registry()
    out = tmp_path / "ep.csv"
    assert main(["simulate", "--duration", "1", "--effect", "my_effect", "--out", str(out)]) == 2
    assert "my_effect" in capsys.readouterr().err and not out.exists()
    assert main(["simulate", "--plugins", "--duration", "1", "--effect", "my_effect",
                 "--out", str(out)]) == 0
    assert "plug-in effects loaded: my_effect (rigctl_test_effects_pkg:ThermalKineticFriction)" \
        in capsys.readouterr().err


def test_entry_point_effect_is_found_and_usable_by_name(installed_example):
    found = entry_point_effects()
    assert "my_effect" in [c.name for c in found]
    reg = effect_registry()
    assert reg["my_effect"].__module__ == "rigctl_test_effects_pkg"
    spec = build_model("paper", effects=["my_effect"], registry=reg)
    res = Simulator(spec).run(DRIVE)
    assert not np.array_equal(res.ft_N, Simulator(build_model("paper")).run(DRIVE).ft_N)


def test_entry_point_used_from_the_cli_without_effect_file(installed_example, tmp_path):
    out = tmp_path / "ep.csv"
    assert main(["simulate", "--velocity", "1e-4", "--duration", "2", "--effect", "my_effect",
                 "--out", str(out)]) == 0
    assert read_csv(out).n_samples == 2 * 1024 + 1


def test_effect_file_wins_over_an_entry_point_of_the_same_name(installed_example, tmp_path):
    path = write(tmp_path, "local.py", GOOD_PLUGIN.replace('"soft_stick"', '"my_effect"'))
    reg = effect_registry([path])
    assert reg["my_effect"].__name__ == "SoftStick"


@pytest.mark.parametrize(
    ("target", "says"),
    [("rigctl_test_no_such_mod:Thing", "cannot load"), ("math:pi", "not a subclass")],
)
def test_broken_entry_point_is_named(tmp_path, monkeypatch, target, says):
    dist = tmp_path / "bad_effects-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: bad-effects\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\nbad_one = {target}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(EffectPluginError, match=f"entry point 'bad_one'.*{says}"):
        entry_point_effects()
