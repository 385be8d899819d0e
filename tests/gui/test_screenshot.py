"""`rigctl gui --screenshot OUT.png --tab NAME`: the picture of the chosen tab during a TLRE on the
simulated rig, and one-line refusals (unknown tab, existing or unwritable output, bad --after)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from matplotlib.image import imread

from rigctl.gui.app import main
from rigctl.gui.screenshot import tab_names

ROOT = Path(__file__).resolve().parents[2]


def dark_tiles(png: Path, tile: int = 16) -> int:
    """Tiles of ``tile`` x ``tile`` pixels that are all near black: the camera image (a dark field
    with bright contact spots) has many; text, tables and white plots have none."""
    rgb = imread(str(png))[..., :3]
    h, w = rgb.shape[0] // tile * tile, rgb.shape[1] // tile * tile
    dark = (rgb[:h, :w].max(axis=2) < 0.2).reshape(h // tile, tile, w // tile, tile)
    return int(dark.all(axis=(1, 3)).sum())


@pytest.mark.slow
def test_cli_writes_a_png_of_the_live_tab(tmp_path):
    out = tmp_path / "live.png"
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    proc = subprocess.run(
        [sys.executable, "-m", "rigctl.gui.app", "--screenshot", str(out), "--tab", "live",
         "--after", "4", "--speed", "max"],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rgb = imread(str(out))
    assert rgb.shape[:2] == (900, 1400)
    assert dark_tiles(out) > 30  # the camera image is in the picture
    assert not list(tmp_path.glob(".live.png.*"))  # no temporary file left


@pytest.mark.slow
def test_protocols_tab_is_pictured_and_a_bad_tab_refused(qtbot, tmp_path, capsys):
    out = tmp_path / "protocols.png"
    assert main(["--screenshot", str(out), "--tab", "Protocols", "--after", "2", "--speed", "max"]) == 0
    assert imread(str(out)).shape[:2] == (900, 1400)
    assert dark_tiles(out) == 0  # no camera image: the Protocols tab, not the Live tab
    before = out.read_bytes()
    # existing file: refused without --force, replaced with it
    assert main(["--screenshot", str(out), "--tab", "devices", "--after", "0"]) == 2
    assert "already exists; use --force" in capsys.readouterr().err
    assert out.read_bytes() == before
    # an unknown tab: one line naming it and the tabs there are; nothing written
    bad = tmp_path / "bad.png"
    assert main(["--screenshot", str(bad), "--tab", "plots", "--after", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "--tab 'plots': no such tab" in err and "live" in err and "protocols" in err
    assert not bad.exists()


@pytest.mark.parametrize(("args", "message"), [
    (["--screenshot", "/nonexistent-dir/x.png"], "the folder /nonexistent-dir does not exist"),
    (["--screenshot", "{tmp}/x.jpg"], "name it *.png"),
    (["--screenshot", "{tmp}/x.png", "--after", "-1"], "--after -1"),
    (["--screenshot", "{tmp}/x.png", "--after", "nan"], "--after nan"),
    (["--screenshot", "{tmp}/x.png", "--backend", "real"], "runs the simulated rig"),
])
def test_refusals_are_one_line_before_anything_starts(tmp_path, capsys, args, message):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
    assert not list(tmp_path.iterdir())


def test_tab_names_come_from_the_window(qtbot):
    from PySide6.QtWidgets import QLabel, QTabWidget

    tabs = QTabWidget()
    qtbot.addWidget(tabs)
    for name in ("Devices", "&Runs", " Workbench "):
        tabs.addTab(QLabel(name), name)
    assert tab_names(tabs) == {"devices": 0, "runs": 1, "workbench": 2}
