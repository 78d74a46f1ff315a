"""The paper's accuracy pattern measured and its experiment reproduced (section IV.2).

``pattern_measure`` reads Table I's columns (depth Z, circle diameters, the distance between the first and
last circle) off one complex image, each tested against the measurement's own noise; ``table1`` renders the
robot sweep, calibrates from it (:mod:`psvs.calibrate`) and writes Table I and Fig. 10 beside the paper's.
"""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "pattern_measure": ["check_pattern_sizes", "measure_pattern"],
        "table1": ["PAPER_TABLE1", "ROBOT_OFFSET_MM", "SUPERSAMPLE", "check_pattern_depths", "check_start",
                   "check_table1", "pattern_image", "run_table1", "table_markdown", "write_outputs"],
    },
)
