"""Exceptions of psvs."""


class RigGeometryError(ValueError):
    """The whole rig configuration is physically impossible (e.g. a mirror blocks the other path)."""
