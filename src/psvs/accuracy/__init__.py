"""The paper's accuracy pattern measured and its experiment reproduced (section IV.2).

``pattern_measure`` reads Table I's columns (depth Z, circle diameters, the distance between the first and
last circle) off one complex image, each tested against the measurement's own noise; ``table1`` renders the
robot sweep, calibrates from it (:mod:`psvs.calibrate`) and writes Table I and Fig. 10 beside the paper's.
"""
