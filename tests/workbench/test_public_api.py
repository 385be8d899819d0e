"""The workbench's public API (rigctl/workbench/__init__.py) resolves, lazily."""

from __future__ import annotations

import pytest

import rigctl.workbench as wb


def test_every_public_name_resolves() -> None:
    for name in wb.__all__:
        assert getattr(wb, name) is not None


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'fit'"):
        _ = wb.fit  # type: ignore[attr-defined]


def test_names_moved_to_records_are_re_exported_unchanged() -> None:
    from rigctl.records.dataset import Dataset, prepare_dataset
    from rigctl.records.rig_description import RigDescription

    assert wb.Dataset is Dataset
    assert wb.prepare_dataset is prepare_dataset
    assert wb.RigDescription is RigDescription
