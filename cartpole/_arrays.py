"""Small array helpers shared by the frozen dataclasses."""
from __future__ import annotations

import numpy as np


def readonly(a, dtype=float) -> np.ndarray:
    """A read-only copy of ``a`` as a numpy array of ``dtype`` (frozen dataclasses hold these)."""
    arr = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr
