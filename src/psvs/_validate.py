"""Shared argument checks, in the style of skimage's ``check_nD``: name the argument, the expectation, what came."""
from __future__ import annotations

import math

import numpy as np


def check_points(arr, name: str, dim: int) -> np.ndarray:
    """Return ``arr`` as float64 of shape (N, dim); a single point of shape (dim,) becomes (1, dim).

    NaN is allowed (it marks a missing point); the caller turns it into an invalid row.
    """
    try:
        a = np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a numeric array of shape (N, {dim}), got {type(arr).__name__}") from None
    if a.ndim == 1 and a.shape[0] == dim:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != dim:
        raise ValueError(f"{name} must have shape (N, {dim}), got {a.shape}")
    return a


def check_grey(image, name: str = "image") -> np.ndarray:
    """``image`` as an ndarray if it is a grey (H, W) uint8 image, else ValueError naming ``name``."""
    a = np.asarray(image)
    if a.ndim != 2 or a.dtype != np.uint8:
        raise ValueError(f"{name} must be a grey (H, W) uint8 image, got shape {a.shape} {a.dtype}")
    return a


def check_same_length(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str) -> None:
    """ValueError naming both arrays when ``a`` and ``b`` differ in their number of rows."""
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"{name_a} and {name_b} must have the same number of rows, got {a.shape[0]} and {b.shape[0]}")


def check_positive(value, name: str, unit: str = "") -> float:
    """``value`` as a float when it is a finite number > 0; else TypeError/ValueError naming ``name`` (and its
    ``unit``)."""
    v = check_finite(value, name)
    if v <= 0:
        raise ValueError(f"{name} must be > 0{(' ' + unit) if unit else ''}, got {value!r}")
    return v


def check_nonnegative(value, name: str, unit: str = "") -> float:
    """``value`` as a float when it is a finite number >= 0; else TypeError/ValueError naming ``name`` (and its
    ``unit``)."""
    v = check_finite(value, name)
    if v < 0:
        raise ValueError(f"{name} must be >= 0{(' ' + unit) if unit else ''}, got {value!r}")
    return v


def check_finite(value, name: str) -> float:
    """``value`` as a float when it is a finite number (a bool is not one); else TypeError/ValueError naming
    ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def check_count(value, name: str, least: int = 1) -> int:
    """``value`` as an int if it is a whole number >= ``least`` (not a bool), else ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
    return int(value)


def check_pair(value, name: str) -> tuple[float, float]:
    """``value`` as two finite floats when it is a pair (tuple or list of 2); else ValueError naming ``name``."""
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise ValueError(f"{name} must be a pair of numbers, got {value!r}")
    return (check_finite(value[0], f"{name}[0]"), check_finite(value[1], f"{name}[1]"))
