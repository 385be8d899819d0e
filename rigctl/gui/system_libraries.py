"""Before a real window opens on Linux: are the system libraries of Qt's ``xcb`` platform there?

PySide6's wheels bring Qt but not the X11/xcb libraries of the system. Without one of them Qt stops
with ``Could not load the Qt platform plugin "xcb"`` and a list of every platform it has, which does
not say what to install. ``rigctl gui`` asks the dynamic loader (``ldd`` on the plugin) first and
names what is missing, with the Debian packages that bring it (docs/gui.md, "System libraries").
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

from rigctl.errors import InputError

DEBIAN_PACKAGES = {
    "libxcb-cursor.so.0": "libxcb-cursor0",
    "libxcb-icccm.so.4": "libxcb-icccm4",
    "libxcb-image.so.0": "libxcb-image0",
    "libxcb-keysyms.so.1": "libxcb-keysyms1",
    "libxcb-randr.so.0": "libxcb-randr0",
    "libxcb-render-util.so.0": "libxcb-render-util0",
    "libxcb-render.so.0": "libxcb-render0",
    "libxcb-shape.so.0": "libxcb-shape0",
    "libxcb-shm.so.0": "libxcb-shm0",
    "libxcb-sync.so.1": "libxcb-sync1",
    "libxcb-util.so.1": "libxcb-util1",
    "libxcb-xfixes.so.0": "libxcb-xfixes0",
    "libxcb-xkb.so.1": "libxcb-xkb1",
    "libxcb.so.1": "libxcb1",
    "libX11-xcb.so.1": "libx11-xcb1",
    "libX11.so.6": "libx11-6",
    "libxkbcommon-x11.so.0": "libxkbcommon-x11-0",
    "libxkbcommon.so.0": "libxkbcommon0",
    "libGL.so.1": "libgl1",
    "libEGL.so.1": "libegl1",
    "libfontconfig.so.1": "libfontconfig1",
    "libfreetype.so.6": "libfreetype6",
    "libglib-2.0.so.0": "libglib2.0-0",
    "libgthread-2.0.so.0": "libglib2.0-0",
    "libdbus-1.so.3": "libdbus-1-3",
}
"""The Debian 12 package of each system library the ``xcb`` plugin of PySide6 6.11 loads
(``readelf -d`` of ``libqxcb.so`` and the Qt libraries it needs; ``dpkg -S`` for the package)."""


class SystemLibraryError(InputError):
    """Qt's ``xcb`` platform cannot load: system libraries are missing (the fix is to install
    them; one line, exit 2)."""


def uses_xcb(environ: Mapping[str, str] | None = None, platform: str | None = None) -> bool:
    """Whether Qt will open its window with the ``xcb`` platform: ``QT_QPA_PLATFORM=xcb``, or on
    Linux nothing chosen and no Wayland session to prefer (``offscreen``, ``wayland``... need none
    of these libraries)."""
    env = os.environ if environ is None else environ
    if not (platform or sys.platform).startswith("linux"):
        return False
    chosen = env.get("QT_QPA_PLATFORM", "").strip()
    if chosen:  # "xcb", "xcb:option=value", "wayland;xcb" (a list: the first that loads)
        return chosen.split(";")[0].split(":")[0].strip() == "xcb"
    return not env.get("WAYLAND_DISPLAY")


def xcb_plugin() -> Path:
    """Qt's ``xcb`` platform plugin inside the installed PySide6."""
    from PySide6.QtCore import QLibraryInfo

    plugins = Path(QLibraryInfo.path(QLibraryInfo.LibraryPath.PluginsPath))
    return plugins / "platforms" / "libqxcb.so"


def missing_libraries(plugin: Path) -> list[str]:
    """The libraries ``plugin`` needs that the dynamic loader does not find (``ldd``: "not found"),
    in the order ldd lists them; none if ldd or the plugin is not there (Qt then says it)."""
    ldd = shutil.which("ldd")
    if ldd is None or not plugin.is_file():
        return []
    try:
        out = subprocess.run([ldd, str(plugin)], capture_output=True, text=True, timeout=30,
                             check=False).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    missing: list[str] = []
    for line in out.splitlines():
        name, _, where = line.strip().partition("=>")
        if where.strip() == "not found" and name.strip() not in missing:
            missing.append(name.strip())
    return missing


def problem(missing: list[str]) -> str:
    """One line: what is missing and the ``apt-get`` command that installs it."""
    packages = sorted({DEBIAN_PACKAGES[m] for m in missing if m in DEBIAN_PACKAGES})
    unknown = [m for m in missing if m not in DEBIAN_PACKAGES]
    text = (f"a window needs system libraries that Qt's xcb platform cannot find: "
            f"{', '.join(missing)}")
    if packages:
        text += f"; on Debian or Ubuntu: sudo apt-get install {' '.join(packages)}"
    if unknown:
        text += f"{' and' if packages else ';'} the package(s) providing {', '.join(unknown)}"
    return text + " (docs/gui.md, 'System libraries')"


def check_xcb_libraries() -> None:
    """Raise :class:`SystemLibraryError` naming what is missing, if the window is to open with
    the ``xcb`` platform and a library it needs cannot be loaded."""
    if not uses_xcb():
        return
    missing = missing_libraries(xcb_plugin())
    if missing:
        raise SystemLibraryError(problem(missing))
