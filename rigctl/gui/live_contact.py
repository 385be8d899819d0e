"""P(x) of the newest camera image for the Live tab, as the run analysis defines it.

The run analysis (:mod:`rigctl.records.contact_intensity`, :mod:`rigctl.analysis.contact_stress`,
docs/analysis.md "Contact images") reads Han et al. 2022 Sec. 3.2 as: I(x, t) = sum over y of the
dark-subtracted grey levels, x the normalised length of the **contact region** (0 = back end), kept
in equal bins, and P(x, t) = I(x, t) normalised to a density (mean 1 over x). The Live tab shows
the same quantity for the newest image, with the same functions:

* the contact region and dark level come from :func:`~rigctl.records.contact_intensity.
  find_contact_region`, applied to the last ``RECENT`` images received (instead of frames spread over
  a recorded run), and are looked for again every ``REGION_EVERY`` images (the load changes the
  contact's extent);
* I(x) is binned with :func:`~rigctl.records.contact_intensity.bin_matrix` and turned into P(x)
  with :func:`~rigctl.records.contact_profile.p_density`.

Images are the downsampled ones the run service sends, so the region is in their columns.
"""

from __future__ import annotations

from collections import deque
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from rigctl.data import DataError
from rigctl.records.contact_intensity import (
    N_PROFILE_BINS,
    ContactRegion,
    bin_matrix,
    find_contact_region,
)
from rigctl.records.contact_profile import p_density
from rigctl.storage.reader import RunReader

RECENT = 8
"""Images the contact region is found from."""
REGION_EVERY = 8
"""Images between two searches for the region."""


class _RecentFrames:
    """The few attributes of a RunReader that ``find_contact_region`` reads, over images in memory."""

    path = "live camera images"

    def __init__(self, images: list[NDArray[np.uint8]]) -> None:
        self._images = np.stack(images)

    @property
    def n_frames(self) -> int:
        return int(self._images.shape[0])

    def frames(self, start: int, stop: int) -> tuple[NDArray[np.uint8]]:
        return (self._images[start:stop],)


class LiveProfile:
    """P(x) of each new image over the contact region found in the recent images."""

    def __init__(self, n_bins: int = N_PROFILE_BINS) -> None:
        self.n_bins = n_bins
        self.region: ContactRegion | None = None
        self.problem = ""
        """Why there is no P(x) (no contact visible), empty when there is one."""
        self._recent: deque[NDArray[np.uint8]] = deque(maxlen=RECENT)
        self._since_search = REGION_EVERY
        self._matrix: NDArray[np.float32] | None = None

    def clear(self) -> None:
        self._recent.clear()
        self.region = None
        self._matrix = None
        self._since_search = REGION_EVERY
        self.problem = ""

    @property
    def x_centres(self) -> NDArray[np.float64]:
        """Normalised x of the bins' centres (0 = back end, 1 = front end)."""
        return (np.arange(self.n_bins) + 0.5) / self.n_bins

    def add(self, image: NDArray[np.uint8]) -> NDArray[np.float64] | None:
        """P(x) of ``image`` (``n_bins`` values, mean 1), or None when no contact is visible."""
        if self._recent and self._recent[-1].shape != image.shape:
            self.clear()  # another camera size: start again
        self._recent.append(image)
        self._since_search += 1
        if self.region is None or self._since_search >= REGION_EVERY:
            self._since_search = 0
            self._search()
        region, matrix = self.region, self._matrix
        if region is None or matrix is None:
            return None
        h = image.shape[0]
        cols = image[:, region.col0:region.col1].sum(axis=0, dtype=np.float64) - h * region.dark_level
        profile = (cols @ matrix.astype(np.float64))[None, :]
        density: NDArray[np.float64] = p_density(profile)[0]
        return density if bool(np.all(np.isfinite(density))) else None

    def _search(self) -> None:
        reader = cast(RunReader, cast(Any, _RecentFrames(list(self._recent))))
        try:
            region = find_contact_region(reader)
        except DataError as exc:
            self.region, self._matrix = None, None
            self.problem = str(exc).split(":", 1)[-1].strip() if ":" in str(exc) else str(exc)
            return
        if self.region is None or self.region.width_px != region.width_px:
            self._matrix = bin_matrix(region.width_px, self.n_bins)
        self.region = region
        self.problem = ""
