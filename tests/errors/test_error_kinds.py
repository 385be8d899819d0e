"""Each caller catches only the error kind it can handle (rigctl/errors.py)."""

from __future__ import annotations

import argparse
from typing import Any

import pytest

from drivers.errors import DeviceTimeout, InvalidValueError, LimitError, SettingError
from experiments.errors import PlanError
from rigctl.cli import main as cli
from rigctl.config.errors import ConfigError
from rigctl.data import DataError
from rigctl.errors import DeviceError, InputError, SimulationError, StorageError, UsageError
from rigctl.model import ParameterError
from rigctl.model.plugins import EffectPluginError
from rigctl.workbench import start_error


@pytest.mark.parametrize(
    "kind",
    [UsageError, ConfigError, DataError, StorageError, PlanError, ParameterError, EffectPluginError,
     InvalidValueError, LimitError, SettingError],
)
def test_every_user_fixable_error_is_an_input_error(kind: type[Exception]) -> None:
    assert issubclass(kind, InputError) and issubclass(kind, ValueError)


def test_parameter_error_is_also_a_simulation_error() -> None:
    assert issubclass(ParameterError, SimulationError)
    assert not issubclass(SimulationError, InputError)


def _cli_raising(monkeypatch: pytest.MonkeyPatch, exc: BaseException) -> int:
    def fail(args: argparse.Namespace) -> int:
        raise exc

    parser = argparse.ArgumentParser()
    parser.set_defaults(func=fail)
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    return cli.main([])


@pytest.mark.parametrize(
    ("exc", "code"),
    [
        (UsageError("--speed must be positive"), 2),
        (ConfigError("rig.toml: daq.node_id: must be <= 127"), 2),
        (LimitError("tangential", "target_m", 0.25, 0.2, "m"), 2),
        (SimulationError("core coefficient 'mu_k' set to a non-finite value nan"), 1),
        (DeviceTimeout("daq", 0.3), 1),
    ],
)
def test_cli_exit_code_follows_the_error_kind(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], exc: Exception, code: int
) -> None:
    assert _cli_raising(monkeypatch, exc) == code
    err = capsys.readouterr().err
    assert err == f"rigctl: error: {exc}\n"


def test_a_plain_value_error_is_a_programming_error_not_a_usage_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with pytest.raises(ValueError, match="operands could not be broadcast"):
        _cli_raising(monkeypatch, ValueError("operands could not be broadcast together"))
    assert not issubclass(DeviceError, ValueError)


def test_a_candidate_that_cannot_be_simulated_is_skipped_but_a_bug_is_not(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(start_error, "physically_valid", lambda choice, fns: True)

    def evaluate_raising(exc: Exception) -> Any:
        def evaluate(dataset: object, choice: object, **kwargs: object) -> Any:
            raise exc

        return evaluate

    monkeypatch.setattr(start_error, "evaluate", evaluate_raising(ParameterError("mu_k >= mu_s")))
    assert start_error.score_or_none(None, None, (0.0, 0.0)) is None  # type: ignore[arg-type]
    monkeypatch.setattr(start_error, "evaluate", evaluate_raising(ValueError("shapes (3,) (4,)")))
    with pytest.raises(ValueError, match="shapes"):
        start_error.score_or_none(None, None, (0.0, 0.0))  # type: ignore[arg-type]
