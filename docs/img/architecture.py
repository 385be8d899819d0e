"""Draws docs/img/architecture.png: rigctl's layers and their one-way imports (docs/architecture.md).

Run: ``.venv/bin/python docs/img/architecture.py`` (matplotlib only).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

LAYERS: list[tuple[str, list[tuple[str, str]]]] = [  # top to bottom: (layer, [(package, what)])
    ("user interfaces", [("rigctl.cli", "command line"), ("rigctl.gui", "operator's window")]),
    ("model search,\nanalyses", [
        ("rigctl.workbench", "model vs data: score, fit,\ndiagnose (not the analysis)"),
        ("rigctl.analysis", "the paper's analyses\n(not the workbench)"),
    ]),
    ("records", [("rigctl.records", "reading a record: prepared runs, slip events,\n"
                                    "features, contact images")]),
    ("glue", [
        ("experiments", "protocols, dry run,\nrunner, safe state"),
        ("rigctl.acquisition", "recording\nsession"),
        ("rigctl.storage / io", "run files,\nCSV format"),
        ("rigctl.config, rigs", "configuration,\nopening a rig"),
    ]),
    ("simulated devices", [("sim_devices", "virtual rig, wire servers,\nin-process devices, faults")]),
    ("physics", [("rigctl.model", "stick-slip engine,\neffects, parameters")]),
    ("devices", [("drivers", "interfaces, real drivers, limits,\nerrors, value checks")]),
]
COLOURS = ["#d9e8f5", "#f0e4f0", "#e0f0ee", "#e3f0d8", "#f6e6cc", "#f3d9d9", "#e6e0f0"]


def draw(path: Path) -> None:
    fig, ax = plt.subplots(figsize=(12.5, 10.2))
    ax.set_xlim(0, 13)
    ax.set_ylim(-0.6, len(LAYERS) * 1.5 + 0.2)
    ax.axis("off")
    centres: list[float] = []
    for row, (layer, boxes) in enumerate(LAYERS):
        y = (len(LAYERS) - 1 - row) * 1.5 + 0.2
        centres.append(y + 0.5)
        ax.text(0.05, y + 0.5, layer, ha="left", va="center", fontsize=10, style="italic",
                color="#444444")
        x0, width = 1.9, 9.4
        w = width / len(boxes)
        for i, (name, what) in enumerate(boxes):
            x = x0 + i * w
            ax.add_patch(FancyBboxPatch((x + 0.06, y), w - 0.12, 1.0,
                                        boxstyle="round,pad=0.02,rounding_size=0.12",
                                        fc=COLOURS[row], ec="#555555", lw=1.0))
            ax.text(x + w / 2, y + 0.68, name, ha="center", va="center", fontsize=9.5,
                    weight="bold")
            ax.text(x + w / 2, y + 0.3, what, ha="center", va="center", fontsize=7.8)
    for upper, lower in zip(centres[:-1], centres[1:], strict=True):
        ax.add_patch(FancyArrowPatch((11.6, upper - 0.52), (11.6, lower + 0.52),
                                     arrowstyle="-|>", mutation_scale=14, lw=1.4, color="#333333"))
    ax.text(11.8, (centres[2] + centres[3]) / 2, "imports:\none way,\ndownwards", ha="left",
            va="center", fontsize=9)
    ax.add_patch(FancyArrowPatch((6.45, centres[0]), (6.75, centres[0]), arrowstyle="-|>",
                                 mutation_scale=12, lw=1.2, color="#333333"))
    ax.text(6.6, centres[0] - 0.62, "rigctl gui starts the window", ha="center", va="center",
            fontsize=7.5, color="#333333")
    ax.text(6.9, -0.35,
            "Small shared modules: rigctl.errors (error kinds), rigctl.status (run status), "
            "rigctl.teardown. Checked by lint-imports (pyproject.toml).",
            ha="center", va="center", fontsize=8.3, color="#333333")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    draw(Path(__file__).with_name("architecture.png"))
