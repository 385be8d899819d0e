"""`rigctl config show`: the effective configuration as TOML; bad files are one-line errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigctl.cli.main import main
from rigctl.config import ENV_VAR, default_config, parse_config


def test_show_prints_the_defaults_as_valid_toml(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(ENV_VAR, raising=False)
    assert main(["config", "show"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("# rigctl rig configuration; source: built-in defaults")
    assert parse_config(out) == default_config()


def test_show_applies_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "rig.toml"
    path.write_text("[normal_stage.limits]\nmax_force_N = 450\n")
    assert main(["config", "show", "--config", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"source: {path}" in out
    assert parse_config(out).normal_stage.limits.max_force_N == 450.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            '[normal_stage.limits]\nmax_force_N = "abc"\n',
            'normal_stage.limits.max_force_N: expected a number, got "abc"',
        ),
        ("[camera]\nfps = 30\n", "camera.fps: unknown key; known keys here:"),
        ("[rig\n", "invalid TOML"),
    ],
)
def test_bad_files_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(text)
    assert main(["config", "show", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}: {message}" in err, err


def test_the_command_names_the_same_environment_variable() -> None:
    from rigctl.cli import cmd_config

    assert cmd_config.ENV_VAR == ENV_VAR


def test_show_needs_an_action(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config"]) == 2
    assert "ACTION" in capsys.readouterr().err
