"""The kernel's array layout and module boundaries (rigctl/model/layout.py, rigctl/model/kernel/)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from rigctl.model import Drive, Simulator, build_model, layout

MODEL_DIR = Path(__file__).resolve().parents[2] / "rigctl" / "model"

GROUPS = {"P_": "N_PARAMS", "S_": "N_FSTATE", "I_": "N_ISTATE", "W_": "N_WROWS",
          "K_": "N_KROWS", "O_": "N_OROWS", "F_": "N_FROWS", "E_": "N_ECOLS"}


def test_every_slot_group_numbers_its_slots_0_to_n_minus_1():
    for prefix, count in GROUPS.items():
        slots = sorted(v for k, v in vars(layout).items() if k.startswith(prefix)
                       and isinstance(v, int) and k != "FN_CONTACT_MIN_N")
        assert slots == list(range(getattr(layout, count))), prefix


def test_no_module_of_the_model_imports_a_private_name_from_another():
    offenders = []
    for path in MODEL_DIR.rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("rigctl"):
                offenders += [f"{path.name}: {node.module}.{a.name}" for a in node.names
                              if a.name.startswith("_") and a.name != "__future__"]
    assert not offenders, offenders


def test_result_channels_are_contiguous_views_of_the_output_tables():
    res = Simulator(build_model("paper")).run(Drive.constant(300.0, 1e-4, 2.0))
    for name in ("ft_N", "f_interface_N", "x_specimen_m", "v_specimen_m_s", "x_stage_m", "fn_N",
                 "stage", "slipping"):
        arr = getattr(res, name)
        assert arr.flags.c_contiguous and arr.shape == res.t_s.shape, name
    assert res.stage.dtype == np.uint8 and res.slipping.dtype == np.bool_
    assert set(np.unique(res.slipping.view(np.uint8))) <= {0, 1}
    assert res.slipping.any() and (res.stage == 1).any()  # the run had a slip
