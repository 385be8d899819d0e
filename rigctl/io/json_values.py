"""Values made plain JSON: what ``json.dumps(..., allow_nan=False)`` takes and a strict parser reads.

JSON has no NaN or infinity (a run killed before its end time, a record of one sample, a parameter
the data do not determine all have NaN figures): they become null. Numpy scalars and arrays
become Python values.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def jsonable(x: Any) -> Any:
    """Plain JSON values: NaN/inf -> None, numpy scalars and arrays -> Python."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, bool | np.bool_):
        return bool(x)
    if isinstance(x, int | np.integer):
        return int(x)
    if isinstance(x, float | np.floating):
        v = float(x)
        return v if math.isfinite(v) else None
    return x
