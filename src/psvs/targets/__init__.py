"""Targets in complex images: what a target looks like through the two views and how it is found.

Every target psvs reads is dark discs on a light ground, seen twice. One blob finder (``discs``) and one
rim refinement (``rim``) serve them all; which disc is whose twin is decided by one test of the rig's
epipolar geometry (``twins.twin_distances_px``, on :func:`psvs.optics.project.epipolar_curves_px`), grown
over a card's many discs (``twins.pair_twins``) or enumerated over the paper's row of five (``pattern``).
The paper's accuracy pattern (``pattern``, Fig. 9) and the calibration cards (``detect``: circle grids;
``charuco``; ``grid``: OpenCV's finders; ``lattice`` labels a grid's discs; ``target_points`` and
``target_file`` say what a card is) are found here; what is computed from them lives above: calibration in
:mod:`psvs.calibrate`, the paper's measurements in :mod:`psvs.accuracy`.
"""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "detect": ["CARD_DEPTHS_MM", "MIN_DISC_PX", "detect_target"],
        "discs": ["MAX_DIAMETER_PX", "MIN_AREA_PX"],
        "pattern": ["PatternDetection", "detect_circles", "detect_pattern", "detect_with_start", "disc_size_range_px",
                    "order_along_row", "perfect_matchings"],
        "rim": ["EDGE_PX", "Ellipse"],
        "target_file": ["dumps_target", "load_target", "target_from_text"],
        "target_points": ["Target", "TargetDetection", "target_points_mm"],
        "twins": ["twin_distances_px"],
    },
)
