"""Exceptions of psvs.

A command's bad input is a ``ValueError``/``TypeError``/``OSError`` (exit status 2). A measurement that the
data cannot answer is a :class:`MeasurementError` (exit status 1): the input was well formed, but what it
shows is inconsistent or does not pin the answer, so psvs says why instead of printing a number."""


class RigGeometryError(ValueError):
    """The whole rig configuration is physically impossible (e.g. a mirror blocks the other path)."""


class MeasurementError(Exception):
    """The data cannot give a right answer: they disagree with what was expected beyond their noise (a
    pattern's spacing or diameters), or they cannot pin the unknowns (too few distinct points, an
    ill-conditioned fit). The message says which and by how much."""
