"""Colour superposition of the contact spots of three frames (CSI, Sec. 3.3, Figs. 8-9, 12).

Han et al. 2022, Sec. 3.3: the spots of three frames at tangential forces Ft,ini < Ft,pro < Ft,fin
are superposed, "blue, green and red ... representing the contact spots corresponding to the three
tangential force. Here, sky blue, purple, yellow and black are used for representing different
superposition combinations." Reading of the colours (each pixel by the frames it is in contact in;
A = first, B = middle, C = last frame):

=========  ==============  ======================================================  ====================
code       colour          paper's words                                           category (pie)
=========  ==============  ======================================================  ====================
A          blue            "the initial contact point disappears"                  contact separation
B          green           "the new contact point disappears"                      contact separation
A B        sky blue        "the initial contact point grows and then disappears"   contact separation
C          red             a contact point appearing by the last frame             new contact
A C        purple          "contact area growth"                                   area growth
B C        yellow          "contact area growth"                                   area growth
A B C      black           "the initial contact area grows and always exists"      black-region growth
=========  ==============  ======================================================  ====================

The four categories of the pie chart (Figs. 9b, d, f) are read as: **contact separation**, a pixel in
contact before but not in the last frame; **new contact**, only in the last frame; **area growth**,
in the last frame and in one earlier frame; **black-region growth**, in all three. Each proportion
is its pixel count over the pixels in contact in any of the three frames, so they sum to 1. Pixels
in no frame are white.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

COLOURS: dict[int, tuple[int, int, int]] = {
    0: (255, 255, 255),   # no contact: white
    1: (0, 0, 255),       # A: blue
    2: (0, 170, 0),       # B: green
    3: (0, 190, 255),     # A B: sky blue
    4: (230, 0, 0),       # C: red
    5: (150, 0, 200),     # A C: purple
    6: (240, 200, 0),     # B C: yellow
    7: (0, 0, 0),         # A B C: black
}
"""RGB of each membership code ``A + 2 B + 4 C``."""

COLOUR_NAMES: dict[int, str] = {1: "blue", 2: "green", 3: "sky blue", 4: "red", 5: "purple",
                                6: "yellow", 7: "black"}

CATEGORIES: dict[str, tuple[int, ...]] = {
    "contact separation": (1, 2, 3),
    "new contact": (4,),
    "area growth": (5, 6),
    "black-region growth": (7,),
}
"""The pie chart's categories and the codes they gather (module docstring)."""


def membership(first: NDArray[np.bool_], middle: NDArray[np.bool_],
               last: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """Per pixel the code ``A + 2 B + 4 C`` of the frames it is in contact in (0..7)."""
    a, b, c = (np.asarray(m, dtype=bool) for m in (first, middle, last))
    if not (a.shape == b.shape == c.shape) or a.ndim != 2:
        raise ValueError(f"CSI needs three 2-D masks of one shape, got {a.shape}, {b.shape}, "
                         f"{c.shape}")
    return (a.astype(np.uint8) + 2 * b.astype(np.uint8) + 4 * c.astype(np.uint8)).astype(np.uint8)


def csi_image(code: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """(H, W, 3) RGB colour superposition image of a membership code map."""
    lut = np.array([COLOURS[k] for k in range(8)], dtype=np.uint8)
    return lut[code]


@dataclass(frozen=True)
class CsiProportions:
    """Pixel counts per colour and the pie chart's proportions."""

    counts: dict[str, int]
    """Pixels per colour name (blue ... black)."""
    proportions: dict[str, float]
    """Per category (CATEGORIES), over the pixels in contact in any frame; sum 1 (NaN if none)."""
    n_contact_px: int

    def to_dict(self) -> dict[str, object]:
        return {"pixels_per_colour": dict(self.counts), "proportions": dict(self.proportions),
                "contact_pixels": self.n_contact_px}


def proportions(code: NDArray[np.uint8]) -> CsiProportions:
    """Counts per colour and the category proportions of a membership code map."""
    hist = np.bincount(np.asarray(code, dtype=np.uint8).ravel(), minlength=8)
    total = int(hist[1:].sum())
    counts = {COLOUR_NAMES[k]: int(hist[k]) for k in range(1, 8)}
    props = {name: (float(sum(int(hist[k]) for k in codes)) / total if total else float("nan"))
             for name, codes in CATEGORIES.items()}
    return CsiProportions(counts, props, total)
