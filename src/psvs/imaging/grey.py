"""Grey levels as an 8-bit image."""
from __future__ import annotations

import numpy as np


def to_grey8(image) -> np.ndarray:
    """Grey levels (any real dtype, any shape) rounded and clipped to 0..255, uint8.

    Examples
    --------
    >>> to_grey8([-3.0, 12.4, 12.6, 300.0])
    array([  0,  12,  13, 255], dtype=uint8)
    """
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
