"""psvs: the Pseudo Stereo Vision System of Pachidis & Lygouras as software.

One camera looks through four 45 deg mirrors (M1 a half-silvered glass plate); every frame superimposes
the views of two ideal parallel virtual cameras. Lengths are mm, pixel quantities px, angles rad.
"""
from psvs.errors import RigGeometryError
from psvs.optics.rig import Camera, MirrorExtent, Mirrors, Rig, default_rig

__all__ = ["Camera", "MirrorExtent", "Mirrors", "Rig", "RigGeometryError", "default_rig"]
__version__ = "0.1.0"
