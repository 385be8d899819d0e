"""The Workbench tab shows each plug-in candidate's fitted parameters: as its fit arrives during a
diagnosis round (values, ``±?``: a candidate fit takes no covariance) and after the round with the
1-sigma uncertainties taken at the fitted values. Fed as the worker reports (progress lines, then
the round's view), so the fast tier renders the tab without fitting."""

from __future__ import annotations

import math
import os

import pytest

from rigctl.gui.workbench_jobs import (
    PARAMS_TAG,
    CandidateParams,
    DiagnoseView,
    ParamValue,
    RankingRow,
    part_done,
)
from rigctl.gui.workbench_panel import WorkbenchPanel

DURING = CandidateParams("my_waviness", 1.21, (
    ParamValue("a_cos", 0.0312, None, "-"),
    ParamValue("a_sin", -0.0405, None, "-"),
    ParamValue("wavelength_m", 6.02e-4, None, "m"),
), final=False)
AFTER = CandidateParams("my_waviness", 1.21, (
    ParamValue("a_cos", 0.0312, 0.0021, "-"),
    ParamValue("a_sin", -0.0405, 0.0019, "-"),
    ParamValue("wavelength_m", 6.02e-4, 3.1e-6, "m"),
), final=True)
OFF = CandidateParams("my_drag", 3.26, (ParamValue("c_N_s_per_m", 0.0, None, "N s/m"),),
                      final=True, note="no uncertainty: the Jacobian is singular")


@pytest.fixture
def panel(qtbot):
    p = WorkbenchPanel(workers=1)
    qtbot.addWidget(p)
    p.resize(1280, 820)
    yield p
    p.shutdown()


def _cells(panel: WorkbenchPanel) -> list[list[str]]:
    t = panel.plugin_table
    return [[t.item(r, c).text() for c in range(t.columnCount())] for r in range(t.rowCount())]


def test_the_progress_line_carries_the_parameters_both_ways():
    text = AFTER.to_text()
    assert text.startswith(PARAMS_TAG)
    assert CandidateParams.from_text(text) == AFTER
    assert CandidateParams.from_text(DURING.to_text()) == DURING
    assert CandidateParams.from_text("  fitted wear: error 3.26") is None
    assert DURING.params[0].text() == "0.0312 ± ?"
    assert AFTER.params[2].text() == "0.000602 ± 3.1e-06 m"


def test_the_progress_bar_follows_each_part_of_the_step():
    assert part_done("screened wear: 3.2 (score 4.1, best at the off, 12 evaluations) "
                     "[3/12, about 40 s left in this round]") == 0.25
    assert part_done("fitted wear + stribeck: 5.1 -> 3.2 in 40 s [2/2]") == 1.0
    assert math.isnan(part_done("identifying paper on 40 slip events ..."))


def test_plugin_parameters_show_during_and_after_the_round(panel, qtbot, tmp_path):
    assert panel.plugin_table.isHidden()  # no plug-in candidate: no table
    panel._on_progress("  fitted wear: error 3.26 (base 3.26; 22 simulations)", 0.5)
    assert panel.plugin_table.rowCount() == 0
    panel._on_progress(DURING.to_text(), math.nan)  # as the worker reports a candidate's fit
    assert not panel.plugin_table.isHidden()
    cells = _cells(panel)
    assert [row[1] for row in cells] == ["a_cos", "a_sin", "wavelength_m"]
    assert cells[0][0] == "my_waviness" and cells[1][0] == ""
    assert all("± ?" in row[2] for row in cells)
    assert "no uncertainty yet" in cells[0][3]
    assert "my_waviness (error 1.21): a_cos = 0.0312 ± ?" in panel.log.toPlainText()
    assert PARAMS_TAG not in panel.progress.format()  # the line is not shown as progress

    view = DiagnoseView(
        "paper", 3.26,
        [RankingRow("my_waviness", 1.21, 0.63, -140.0, True, "peaks vs cumulative slip"),
         RankingRow("wear", 3.26, 0.0, 9.1, False, "nothing (no improvement)"),
         RankingRow("my_drag", 3.26, 0.0, 4.6, False, "nothing (no improvement)")],
        "my_waviness", ["my_waviness"], "", None, [], [AFTER, OFF])
    panel._show_ranking(view)
    cells = _cells(panel)
    assert cells[0][2] == "0.0312 ± 0.0021"
    assert cells[1][2] == "-0.0405 ± 0.0019"
    assert cells[2][2] == "0.000602 ± 3.1e-06 m"
    assert "no uncertainty yet" not in cells[0][3]
    assert cells[3][0] == "my_drag" and cells[3][2] == "0 ± ? N s/m"
    assert "no uncertainty" in cells[3][3]

    panel.show()
    qtbot.waitExposed(panel)
    out = os.environ.get("RIGCTL_TEST_PNG_DIR")
    path = (tmp_path if not out else __import__("pathlib").Path(out)) / "workbench_plugin_params.png"
    assert panel.grab().save(str(path))
    assert path.stat().st_size > 10_000

    panel.set_data([])  # new data: the results, plug-in parameters included, start again
    assert panel.plugin_table.rowCount() == 0 and panel.plugin_table.isHidden()
