"""Calibrating a build: bundle adjustment of the exact optics from hand-held card views and/or the paper's
robot sweep.

``folder`` reads a calibration folder (card views, ``sweep.csv``, ``target.toml``) and calls ``bundle``
(the lens, the plate, the mirrors' pose errors and every target pose); ``sweep`` is the robot sweep as
calibration data; ``capture`` is the assistant that says which card views are good and when there are
enough; ``synthetic`` and ``handheld`` simulate card views and a hand-held video; ``report`` writes a
calibration's residuals. Targets are found by :mod:`psvs.targets`.
"""
