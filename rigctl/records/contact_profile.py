"""The equivalent stress distribution P(x, t) of a contact image's intensity profile (Sec. 3.2, 5.1).

Han et al. 2022, Sec. 3.2: "If the real contact area linearly changes with the change of normal force,
the distribution of contact area on the interface can approximately represent the distribution of
interface stress." The equation that follows was lost; we read it as I(x, t) normalised along x:

    P(x, t) = I(x, t) / integral_0^1 I(x', t) dx'          (a density: its mean over x is 1)

with x the normalised length of the contact, 0 the back end, 1 the front end (Fig. 7a). Sec. 5.1
(Fig. 13): "the contact area is divided into 10 parts along the x direction, and the intensity
proportion of local contact image is calculated as the equivalent stress distribution P(k, t)":

    P(k, t) = sum_{x in part k} I(x, t) / sum_x I(x, t),   k = 1..10,   sum_k P(k, t) = 1

the model's convention for its element shares P(i) (docs/model.md: element i covers x in
[i/N, (i+1)/N), element 0 at the back end). Negative bin sums (noise below the dark level) count
as 0; a frame without contact has no P (NaN).

The analysis (:mod:`rigctl.analysis.contact_stress`) and the workbench's image features
(:mod:`rigctl.records.image_features`) both read P through these two functions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rigctl.data import FloatArray

MODEL_BINS = 10
"""Parts of the contact in the paper's model (Sec. 5.1) and in rigctl's default model (N = 10)."""


def p_density(profile: NDArray[np.floating]) -> FloatArray:
    """P(x, t) as a density over normalised x (rows: frames, columns: bins of x; NaN without contact)."""
    prof = np.clip(np.asarray(profile, dtype=np.float64), 0.0, None)
    if prof.ndim == 1:
        prof = prof[None, :]
    total = prof.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(total > 0, prof * prof.shape[1] / total, np.nan)
    return out


def p_bins(profile: NDArray[np.floating], n_parts: int = MODEL_BINS) -> FloatArray:
    """P(k, t): the share of the contact intensity in each of ``n_parts`` equal parts (sum 1).

    The profile's bins must split evenly into the parts (100 bins into 10).
    """
    prof = np.clip(np.asarray(profile, dtype=np.float64), 0.0, None)
    if prof.ndim == 1:
        prof = prof[None, :]
    nb = prof.shape[1]
    if n_parts < 1 or nb % n_parts:
        raise ValueError(f"{nb} profile bins do not split into {n_parts} equal parts")
    parts = prof.reshape(prof.shape[0], n_parts, nb // n_parts).sum(axis=2)
    total = parts.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, parts / total, np.nan)
