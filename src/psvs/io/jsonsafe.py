"""Values as JSON can hold them: JSON has no NaN or infinity (null in their place) and no NumPy types."""
from __future__ import annotations

import numpy as np


def json_safe(value):
    """``value`` with every NumPy array, scalar and tuple turned into plain lists, floats, ints and bools,
    and every NaN or infinite float into None, recursively through dicts and lists.

    Examples
    --------
    >>> json_safe({"z_mm": np.array([1.5, np.nan]), "n": np.int64(2), "ok": np.bool_(True)})
    {'z_mm': [1.5, None], 'n': 2, 'ok': True}
    """
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value
