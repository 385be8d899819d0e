"""`rigctl gui` names the system libraries Qt's xcb platform cannot find (one line, exit 2) instead of
Qt's plugin error; offscreen and Wayland need none of them."""

from __future__ import annotations

import subprocess

import pytest

from rigctl.gui import system_libraries
from rigctl.gui.system_libraries import DEBIAN_PACKAGES, missing_libraries, uses_xcb, xcb_plugin

LDD_OUTPUT = """\
\tlinux-vdso.so.1 (0x00007ffd)
\tlibGL.so.1 => /lib/x86_64-linux-gnu/libGL.so.1 (0x00007fa1)
\tlibxcb-icccm.so.4 => not found
\tlibxcb-keysyms.so.1 => not found
\tlibxcb-icccm.so.4 => not found
\tlibvendor-thing.so.2 => not found
"""


def test_rigctl_gui_names_the_missing_libraries_in_one_line_and_exits_2(monkeypatch, capsys):
    from rigctl.cli.main import main

    def no_window(*args: object, **kw: object) -> None:
        raise AssertionError("the window was built although a library it needs is missing")

    monkeypatch.setenv("QT_QPA_PLATFORM", "xcb")
    monkeypatch.setattr("rigctl.gui.main_window.MainWindow", no_window)
    monkeypatch.setattr(system_libraries, "missing_libraries",
                        lambda plugin: ["libxcb-icccm.so.4", "libxcb-keysyms.so.1"])
    assert main(["gui", "--in-process"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "libxcb-icccm.so.4, libxcb-keysyms.so.1" in err
    assert "sudo apt-get install libxcb-icccm4 libxcb-keysyms1" in err


def test_the_platform_decides_whether_the_libraries_are_needed():
    assert uses_xcb({"QT_QPA_PLATFORM": "xcb"}, "linux")
    assert uses_xcb({"QT_QPA_PLATFORM": "xcb:dpi=96"}, "linux")
    assert uses_xcb({}, "linux")  # Qt's default on Linux without a Wayland session
    assert not uses_xcb({"QT_QPA_PLATFORM": "offscreen"}, "linux")
    assert not uses_xcb({"QT_QPA_PLATFORM": "wayland;xcb"}, "linux")
    assert not uses_xcb({"WAYLAND_DISPLAY": "wayland-0"}, "linux")
    assert not uses_xcb({"QT_QPA_PLATFORM": "xcb"}, "darwin")


def test_ldd_s_not_found_lines_are_the_missing_libraries(monkeypatch, tmp_path):
    plugin = tmp_path / "libqxcb.so"
    plugin.write_bytes(b"")
    monkeypatch.setattr(system_libraries.shutil, "which", lambda name: "/usr/bin/ldd")
    monkeypatch.setattr(system_libraries.subprocess, "run", lambda cmd, **kw:
                        subprocess.CompletedProcess(cmd, 0, stdout=LDD_OUTPUT, stderr=""))
    missing = missing_libraries(plugin)
    assert missing == ["libxcb-icccm.so.4", "libxcb-keysyms.so.1", "libvendor-thing.so.2"]
    text = system_libraries.problem(missing)
    assert "sudo apt-get install libxcb-icccm4 libxcb-keysyms1 and the package(s) providing " \
           "libvendor-thing.so.2" in text
    monkeypatch.setattr(system_libraries.shutil, "which", lambda name: None)
    assert missing_libraries(plugin) == []  # no ldd: Qt says what it says


@pytest.mark.skipif(not xcb_plugin().is_file(), reason="no xcb plugin in this PySide6")
def test_every_library_missing_here_has_its_package_named():
    """On this machine (ldd on the real plugin): whatever is missing is in the package table."""
    assert set(missing_libraries(xcb_plugin())) <= set(DEBIAN_PACKAGES)
