"""Targets in complex images: what a target looks like through the two views and how it is found.

Every target psvs reads is dark discs on a light ground, seen twice. One blob finder (``discs``) and one
rim refinement (``rim``) serve them all; which disc is whose twin is decided by the rig's epipolar geometry
(``twins`` for the many discs of a card, ``pairing`` for the paper's row of five, both on
:func:`psvs.optics.project.epipolar_curve_px`). The paper's accuracy pattern (``pattern``, Fig. 9) and the
calibration cards (``detect``: circle grids, ``charuco``, ``grid``: OpenCV's finders; ``lattice`` labels a
grid's discs; ``target_points`` and ``target_file`` say what a card is) are found here; what is computed
from them lives above: calibration in :mod:`psvs.calibrate`, the paper's measurements in :mod:`psvs.accuracy`.
"""
